//! How the GPU passes cut a frame: the tile side and how many tiles share one submission,
//! chosen from the device's limits and memory budget, the batch loop that records them, and
//! the out-of-memory retry. Shared by the forward and the backward, so both cut frames by the
//! same policy. Each tile binds its own buffers (one descriptor set per tile and pass); a batch
//! records several tiles into one command buffer, submits once, waits, reads every tile back,
//! and the [`CommandBatch`] (command pool and descriptor pools) is reset for the next batch.
use super::{Params, RenderOptions, RenderStats, TILE};
use crate::tiling::Rect;
use crate::vk::{CommandBatch, Context, MemoryBudget};
use crate::{Error, Result};

/// Most tiles recorded into one submission: batches amortise the submission and its wait,
/// and a few tiles suffice for that; more would only hold more device memory at once.
pub(crate) const MAX_TILES_PER_BATCH: usize = 8;
/// A frame that does not fit the budget as one tile is cut so that at least this many tiles
/// fit it together (one batch records them all).
const MIN_TILES_PER_BATCH: u64 = 2;

/// Device bytes of one frame tile, assuming the worst halo everywhere.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Footprint {
    /// The largest single buffer (bound as one storage buffer: at most the device's range).
    pub largest_binding: u64,
    /// All the tile's buffers together.
    pub total: u64,
}

/// Tile side (a multiple of 16) and tiles per submission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct TilePlan {
    pub tile: usize,
    pub tiles_per_batch: usize,
}

/// Bytes a render may plan to hold on the device at once: half of what this process may still
/// allocate as measured (VK_EXT_memory_budget, or system memory for a CPU device; the rest is
/// headroom for the allocator's blocks, the driver and other programs starting meanwhile),
/// else a quarter of the device-local heap (other programs may already hold much of it, and
/// nothing says how much).
pub(crate) fn planning_bytes(budget: MemoryBudget) -> u64 {
    if budget.measured {
        budget.available_bytes / 2
    } else {
        budget.available_bytes / 4
    }
}

pub(crate) fn round_to_tile(pixels: usize) -> usize {
    pixels.max(1).div_ceil(TILE) * TILE
}

/// `tile x tile` cores in row-major order, the last row and column cut by the frame.
pub(crate) fn frame_cores(width: usize, height: usize, tile: usize) -> Vec<Rect> {
    let mut cores = Vec::new();
    for y0 in (0..height).step_by(tile) {
        for x0 in (0..width).step_by(tile) {
            cores.push(Rect { x0, y0, x1: (x0 + tile).min(width), y1: (y0 + tile).min(height) });
        }
    }
    cores
}

/// Runs `attempt` with the options' tile side and batch size, or else those planned from the
/// device's limits and memory budget; while it runs out of device memory, again with tiles
/// half as large (and no more per batch), then fewer tiles per batch. Fails with
/// [`Error::OutOfDeviceMemory`] when one 16 px tile alone does not fit.
pub(crate) fn run_tiled<T>(
    ctx: &Context,
    params: &Params,
    options: &RenderOptions,
    footprint: impl Fn(usize) -> Footprint,
    mut attempt: impl FnMut(TilePlan) -> Result<T>,
) -> Result<T> {
    let info = ctx.info();
    let limits = Limits {
        // The largest bindings are vec4 per read pixel and layer, some of them texel buffers.
        largest_binding: u64::from(info.max_storage_buffer_range)
            .min(info.max_allocation_bytes)
            .min(u64::from(info.max_texel_buffer_elements) * 16),
        bytes: planning_bytes(ctx.memory_budget()),
    };
    // Never more per batch than the frame has tiles: a retry then starts from what really ran.
    let tiles_per_batch = |tile: usize| {
        let wanted = match options.tiles_per_batch {
            Some(n) => n.max(1),
            None => limits.tiles_per_batch(footprint(tile)),
        };
        wanted.min(params.width.div_ceil(tile) * params.height.div_ceil(tile)).max(1)
    };
    let tile = match options.tile {
        Some(tile) => round_to_tile(tile),
        None => limits.tile_size(params.width, params.height, &footprint),
    };
    let mut plan = TilePlan { tile, tiles_per_batch: tiles_per_batch(tile) };
    loop {
        match attempt(plan) {
            // Drivers report a budget they cannot always honour: retry smaller.
            Err(error) if error.is_out_of_memory() => {
                let Some(smaller) = plan.smaller(tiles_per_batch) else {
                    return Err(Error::OutOfDeviceMemory { tile: plan.tile, source: Box::new(error) });
                };
                log::warn!(
                    "out of device memory with {} px tiles, {} per submission; retrying with {} px, {} per submission",
                    plan.tile,
                    plan.tiles_per_batch,
                    smaller.tile,
                    smaller.tiles_per_batch
                );
                plan = smaller;
            }
            result => return result,
        }
    }
}

impl TilePlan {
    /// The next plan after running out of memory: half the tile side with at most as many
    /// tiles per batch (about a quarter of the memory); at 16 px, half the tiles per batch.
    fn smaller(self, tiles_per_batch: impl Fn(usize) -> usize) -> Option<TilePlan> {
        if self.tile > TILE {
            let tile = round_to_tile(self.tile / 2);
            Some(TilePlan { tile, tiles_per_batch: self.tiles_per_batch.min(tiles_per_batch(tile)) })
        } else if self.tiles_per_batch > 1 {
            Some(TilePlan { tile: self.tile, tiles_per_batch: self.tiles_per_batch / 2 })
        } else {
            None
        }
    }
}

/// What a plan must respect on this device.
struct Limits {
    /// Bytes of the largest buffer: the storage-buffer range and the largest allocation.
    largest_binding: u64,
    /// Bytes a batch may hold ([`planning_bytes`]).
    bytes: u64,
}

impl Limits {
    fn fits(&self, footprint: Footprint, bytes: u64) -> bool {
        footprint.largest_binding <= self.largest_binding && footprint.total <= bytes
    }

    /// The whole frame if it fits as one tile; else the largest tile (multiple of 16) of which
    /// [`MIN_TILES_PER_BATCH`] fit together, so batches hold several tiles.
    fn tile_size(&self, width: usize, height: usize, footprint: &impl Fn(usize) -> Footprint) -> usize {
        let mut tile = round_to_tile(width.max(height));
        if self.fits(footprint(tile), self.bytes) {
            return tile;
        }
        while tile > TILE && !self.fits(footprint(tile), self.bytes / MIN_TILES_PER_BATCH) {
            tile = round_to_tile(tile * 3 / 4);
        }
        tile
    }

    /// As many tiles as fit the budget together, at least one, at most [`MAX_TILES_PER_BATCH`].
    fn tiles_per_batch(&self, footprint: Footprint) -> usize {
        let fitting = self.bytes / footprint.total.max(1);
        (fitting as usize).clamp(1, MAX_TILES_PER_BATCH)
    }
}

/// Renders `cores` in batches of `plan.tiles_per_batch`: `record` allocates a tile's buffers
/// and records its passes into the batch, returning what to read back; after the batch's one
/// submission has completed, `collect` takes each tile's read-back in order, and progress is
/// reported per tile. The batch is reused: its command and descriptor pools are reset after
/// each submission, and a tile's buffers are freed once its batch is collected. The stats
/// leave `taps` to the caller.
pub(crate) fn run_batches<T>(
    ctx: &Context,
    cores: &[Rect],
    plan: TilePlan,
    options: &RenderOptions,
    mut record: impl FnMut(&mut CommandBatch, Rect) -> Result<T>,
    mut collect: impl FnMut(Rect, T) -> Result<()>,
) -> Result<RenderStats> {
    let baseline = ctx.allocated_bytes();
    let mut stats = RenderStats {
        device_ns: Some(0.0),
        tiles: cores.len(),
        tile_size: plan.tile,
        tiles_per_batch: plan.tiles_per_batch,
        ..RenderStats::default()
    };
    let mut batch = CommandBatch::new(ctx)?;
    let mut done = 0;
    for batch_cores in cores.chunks(plan.tiles_per_batch.max(1)) {
        let mut tiles = Vec::with_capacity(batch_cores.len());
        for &core in batch_cores {
            tiles.push((core, record(&mut batch, core)?));
            let held = ctx.allocated_bytes().saturating_sub(baseline);
            if options.device_memory_limit.is_some_and(|limit| held > limit) {
                // The testing aid: as if the driver had refused the allocation just made.
                return Err(Error::Allocation(gpu_allocator::AllocationError::OutOfMemory));
            }
            stats.peak_device_bytes = stats.peak_device_bytes.max(held);
        }
        batch.submit_and_wait()?;
        stats.device_ns = stats.device_ns.zip(batch.last_device_time_ns()).map(|(a, b)| a + b);
        for (core, tile) in tiles {
            collect(core, tile)?;
            done += 1;
            if let Some(progress) = options.progress {
                progress(done, cores.len());
            }
        }
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A footprint of `bytes_per_pixel` per core pixel (no halo), tiny bindings.
    fn per_pixel(bytes_per_pixel: u64) -> impl Fn(usize) -> Footprint {
        move |tile| Footprint { largest_binding: 1, total: (tile * tile) as u64 * bytes_per_pixel }
    }

    #[test]
    fn a_frame_that_fits_is_one_tile() {
        let limits = Limits { largest_binding: u64::MAX, bytes: 100 * 100 };
        assert_eq!(limits.tile_size(90, 40, &per_pixel(1)), 96);
    }

    #[test]
    fn a_frame_that_does_not_fit_gets_tiles_of_which_two_fit_together() {
        // 1000x1000 at 1 byte a pixel in 300 kB: tiles must be at most 150 kB (387 px).
        let limits = Limits { largest_binding: u64::MAX, bytes: 300_000 };
        let tile = limits.tile_size(1000, 1000, &per_pixel(1));
        assert_eq!(tile % TILE, 0);
        assert!((tile * tile) as u64 <= 150_000, "tile {tile}");
        // Shrinking by 3/4 steps lands within a factor 4/3 of the largest fitting side.
        assert!(tile * 4 / 3 + TILE > 387, "tile {tile} is needlessly small");
        assert_eq!(limits.tiles_per_batch(per_pixel(1)(tile)), 300_000 / (tile * tile));
        assert!(limits.tiles_per_batch(per_pixel(1)(tile)) >= 2);
    }

    #[test]
    fn the_storage_range_bounds_the_tile_whatever_the_memory() {
        let limits = Limits { largest_binding: 64 * 64, bytes: u64::MAX };
        let binding = |tile: usize| Footprint { largest_binding: (tile * tile) as u64, total: 0 };
        assert_eq!(limits.tile_size(1000, 1000, &binding), 64);
    }

    #[test]
    fn tiles_per_batch_stays_between_one_and_the_cap() {
        let limits = Limits { largest_binding: u64::MAX, bytes: 1000 };
        let footprint = |total| Footprint { largest_binding: 1, total };
        assert_eq!(limits.tiles_per_batch(footprint(5000)), 1, "a tile over the budget still runs alone");
        assert_eq!(limits.tiles_per_batch(footprint(400)), 2);
        assert_eq!(limits.tiles_per_batch(footprint(1)), MAX_TILES_PER_BATCH);
    }

    #[test]
    fn out_of_memory_halves_the_tile_then_the_batch_then_gives_up() {
        let plan = TilePlan { tile: 96, tiles_per_batch: 4 };
        let next = plan.smaller(|_| 8).unwrap();
        assert_eq!(next, TilePlan { tile: 48, tiles_per_batch: 4 }, "never more tiles per batch after a failure");
        assert_eq!(next.smaller(|_| 3).unwrap(), TilePlan { tile: 32, tiles_per_batch: 3 }, "24 rounds up to 32");
        let smallest = TilePlan { tile: TILE, tiles_per_batch: 3 };
        assert_eq!(smallest.smaller(|_| 8), Some(TilePlan { tile: TILE, tiles_per_batch: 1 }));
        assert_eq!(TilePlan { tile: TILE, tiles_per_batch: 1 }.smaller(|_| 8), None);
    }

    #[test]
    fn plans_leave_headroom_and_trust_the_driver_budget_more_than_the_heap_size() {
        let driver = planning_bytes(MemoryBudget { available_bytes: 1 << 30, measured: true });
        let heap = planning_bytes(MemoryBudget { available_bytes: 1 << 30, measured: false });
        assert!(heap < driver && driver < 1 << 30, "heap {heap}, driver {driver}");
    }
}
