//! Tiling as a service (darktable's model): a method declares what the tiler needs — the frame,
//! the tile alignment, the halo a core reads (`FrameTiling`), the device bytes of a tile
//! (`Footprint`) — and records one tile's passes; this module picks the tile side and how
//! many tiles share one submission from the device's limits and the memory budget, runs the
//! batches, retries with smaller tiles when device memory runs out, and reports progress.
//!
//! Every method writes each output pixel from the same sources in the same order whatever the
//! tile (its shaders take the tile's origin and the full frame size), so output is
//! bit-identical for every tile size. The grid and halo math is [`crate::tile_grid`]; the Vulkan
//! calls are `crate::vk`'s. Methods import this module, never the reverse.
use crate::image::Image;
use crate::tile_grid::Rect;
use crate::vk::{CommandBatch, Context, MemoryBudget, ReadBack};
use crate::{Error, Result};

/// Most tiles recorded into one submission: batches amortise the submission and its wait,
/// and a few tiles suffice for that; more would only hold more device memory at once.
pub(crate) const MAX_TILES_PER_BATCH: usize = 8;
/// A frame that does not fit the budget as one tile is cut so that at least this many tiles
/// fit it together (one batch records them all).
const MIN_TILES_PER_BATCH: u64 = 2;
/// On a CPU device (whose memory is the host's), a render holds at most this many times the
/// float32 size of its input unless `--max-memory` says otherwise: a bound derived from the
/// frame, not from what the machine has free (a farm node runs several jobs at once).
pub const CPU_DEVICE_MEMORY_FACTOR: u64 = 3;
/// Without `--max-memory`, tiles may always hold this much: below it the process's fixed cost
/// (binary, driver, compiled pipelines: ~150 MiB on lavapipe) dominates the peak anyway, and
/// cutting small frames or methods whose whole-frame data fills the bound finer would only add
/// submissions.
const MIN_DEFAULT_TILE_BYTES: u64 = 256 << 20;
/// Most work (taps or ray-march steps, as the method counts them) one tile's dispatch may do on
/// a GPU: a few tenths of a second at the ~1e10 simple taps/s of a mid-range card, well inside
/// the display watchdogs (Windows' TDR: 2 s) that kill longer dispatches. CPU devices have no
/// watchdog and are not bounded.
pub const MAX_WORK_PER_TILE: u64 = 2_000_000_000;
/// Side of the smallest tile the out-of-memory retry goes down to, for methods aligned to 1.
const MIN_TILE: usize = 16;

/// What a method keeps from one render of a stack for the next render of the same stack, such
/// as Dr.Bokeh's pass over the pixels that bounds its searches and the stack's upload (a
/// [`crate::render::drbokeh::ResidentStack`]). Whoever hands one to a render vouches that the
/// stack is the one the memo was filled from, unchanged, and makes a new memo when the stack
/// changes: a resident session does, for the stack it holds. One value at a time, of any type:
/// a method that finds another method's value replaces it.
#[derive(Default)]
pub struct StackMemo(std::sync::Mutex<Option<std::sync::Arc<dyn std::any::Any + Send + Sync>>>);

impl StackMemo {
    /// The kept `T`, or `make()`'s, kept from now on.
    pub fn get_or_insert_with<T: std::any::Any + Send + Sync>(&self, make: impl FnOnce() -> T) -> std::sync::Arc<T> {
        let mut kept = self.0.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some(value) = kept.clone().and_then(|value| value.downcast::<T>().ok()) {
            return value;
        }
        let value = std::sync::Arc::new(make());
        *kept = Some(value.clone());
        value
    }

    /// Whether a `T` is kept.
    pub fn holds<T: std::any::Any>(&self) -> bool {
        self.0.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).as_ref().is_some_and(|value| value.is::<T>())
    }
}

/// How to cut and report a render.
#[derive(Clone, Copy, Default)]
pub struct RenderOptions<'a> {
    /// Frame tile side in pixels (rounded up to the method's alignment: 16 for Dr.Bokeh); `None`:
    /// the whole frame if it fits the device's buffer range and memory budget, else the largest
    /// tile of which two fit together.
    pub tile: Option<usize>,
    /// Tiles recorded into one submission; `None`: as many as fit the memory budget together
    /// (at most 8).
    pub tiles_per_batch: Option<usize>,
    /// Bytes the render may hold in all, host and device (`--max-memory`): inputs, output and
    /// tiles. `None`: on a CPU device [`CPU_DEVICE_MEMORY_FACTOR`] times the input's float32
    /// size, on a GPU what the driver's budget leaves.
    pub max_memory: Option<u64>,
    /// Called after each finished tile with (tiles done, tiles in all).
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    /// What a method may keep from this render for the next one of the same stack (a
    /// resident session's): see [`StackMemo`]. `None`: nothing is kept.
    pub stack_memo: Option<&'a StackMemo>,
    /// Testing aid, not a user setting: device memory (bytes over what the device held when
    /// the frame began) past which a tile's allocations count as out of device memory, so the
    /// smaller-tile retry runs on any device. `None` in every real render.
    #[doc(hidden)]
    pub device_memory_limit: Option<u64>,
    /// Testing aid, not a user setting: the work per tile that a GPU's watchdog bound would
    /// allow, on any device (a CPU device has none), so tile growth runs on lavapipe.
    #[doc(hidden)]
    pub max_tile_work: Option<u64>,
}

/// What one render measured.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderStats {
    /// Device time of all passes (timestamp queries), if the queue supports them.
    pub device_ns: Option<f64>,
    /// Frame tiles rendered and their side (after any out-of-memory retries).
    pub tiles: usize,
    pub tile_size: usize,
    /// Tiles recorded into one submission.
    pub tiles_per_batch: usize,
    /// Most device memory this renderer's buffers held at once.
    pub peak_device_bytes: u64,
    /// Source pixels gathered (sum over layers and pixels of the window area): the work.
    pub taps: u64,
    /// Host time in the tile loop: allocating, filling and recording tiles; waiting for their
    /// submissions; reading their results back. The rest of a render's wall time is the
    /// method's own preparation of the frame.
    pub host_record_ns: f64,
    pub host_wait_ns: f64,
    pub host_collect_ns: f64,
}

/// What a method declares about its frame so the service can cut it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FrameTiling {
    pub width: usize,
    pub height: usize,
    /// Tile sides are multiples of this (Dr.Bokeh's 16 px search tiles; 1 where any side works).
    pub align: usize,
    /// float32 bytes of the input (every layer's RGBA + depth): the yardstick of the CPU
    /// device's default memory bound.
    pub input_bytes: u64,
    /// Host bytes the render holds for the whole frame besides its tiles (input and output),
    /// counted against the memory cap.
    pub host_bytes: u64,
    /// Upper bound of the work (taps, ray-march steps) per output pixel: tiles on a GPU keep
    /// their dispatches within [`MAX_WORK_PER_TILE`]. 0: not declared.
    pub work_per_pixel: u64,
}

impl FrameTiling {
    /// A frame of `layers` RGBA + depth float32 inputs rendered to one RGBA float32 image, held
    /// on the host for the whole render (what every method's caller holds).
    pub fn new(width: usize, height: usize, layers: usize, align: usize) -> Self {
        let pixels = (width * height) as u64;
        let input_bytes = pixels * layers as u64 * 20;
        Self {
            width,
            height,
            align: align.max(1),
            input_bytes,
            host_bytes: input_bytes + pixels * 16,
            work_per_pixel: 0,
        }
    }

    /// With [`Self::work_per_pixel`].
    pub fn with_work(self, work_per_pixel: u64) -> Self {
        Self { work_per_pixel, ..self }
    }

    /// Work of a `tile`-sided tile's dispatch.
    fn work(&self, tile: usize) -> u64 {
        (tile.min(self.width) * tile.min(self.height)) as u64 * self.work_per_pixel
    }

    /// The next side to try after `tile`: about 3/4, at least one alignment step smaller (3/4
    /// of 32 rounds back up to 32 with 16 px), at least the smallest tile.
    fn shrink(&self, tile: usize) -> usize {
        self.round(tile * 3 / 4).min(tile - self.align).max(self.min_tile())
    }

    /// The side `pixels` rounds up to.
    pub fn round(&self, pixels: usize) -> usize {
        pixels.max(1).div_ceil(self.align) * self.align
    }

    /// `tile x tile` cores in row-major order, the last row and column cut by the frame.
    pub fn cores(&self, tile: usize) -> Vec<Rect> {
        self.cores_in(Rect { x0: 0, y0: 0, x1: self.width, y1: self.height }, tile)
    }

    /// `tile x tile` cores of `region` (whose corner is aligned) in row-major order, the last
    /// row and column cut by the region.
    fn cores_in(&self, region: Rect, tile: usize) -> Vec<Rect> {
        let mut cores = Vec::new();
        for y0 in (region.y0..region.y1).step_by(tile) {
            for x0 in (region.x0..region.x1).step_by(tile) {
                cores.push(Rect { x0, y0, x1: (x0 + tile).min(region.x1), y1: (y0 + tile).min(region.y1) });
            }
        }
        cores
    }

    /// Pixels of a `tile`-sided core grown by `margin` on every side, clipped to the frame: what
    /// the largest tile of a plan holds. Tiles size their buffers for it, so every tile of the
    /// frame asks the device's pool for the same sizes and takes the memory an earlier tile gave
    /// back ([`crate::vk::Buffer::uninitialised_with_room`]).
    pub fn room(&self, tile: usize, margin: usize) -> usize {
        let side = tile + 2 * margin;
        side.min(self.width) * side.min(self.height)
    }

    /// The smallest tile the retry goes down to.
    fn min_tile(&self) -> usize {
        self.round(MIN_TILE)
    }
}

/// Device bytes of one frame tile, assuming the worst halo everywhere.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Footprint {
    /// The largest single buffer (bound as one storage buffer: at most the device's range).
    pub largest_binding: u64,
    /// All the tile's buffers together.
    pub total: u64,
}

impl Footprint {
    /// `read_bytes` per pixel of a `tile`-sided core grown by `halo` (clipped to the frame),
    /// plus `core_bytes` per core pixel; the largest binding is `binding_bytes` per read pixel.
    pub fn per_pixel(
        frame: &FrameTiling,
        tile: usize,
        halo: usize,
        read_bytes: u64,
        core_bytes: u64,
        binding_bytes: u64,
    ) -> Self {
        let core = (tile.min(frame.width) * tile.min(frame.height)) as u64;
        let read = ((tile + 2 * halo).min(frame.width) * (tile + 2 * halo).min(frame.height)) as u64;
        Footprint { largest_binding: binding_bytes * read.max(core), total: read * read_bytes + core * core_bytes }
    }
}

/// Pixels of the largest core and read rect of a plan's tiles, which every tile's buffers have
/// room for ([`FrameTiling::room`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileRoom {
    pub core: usize,
    pub read: usize,
}

/// Tile side (a multiple of the frame's alignment) and tiles per submission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct TilePlan {
    pub tile: usize,
    pub tiles_per_batch: usize,
    /// Where the side was bounded by the work per dispatch on a GPU (not by memory or the
    /// caller): what [`run_batches`] needs to cut the rest of the frame into larger tiles once
    /// the first batch has shown how fast the device is.
    pub growth: Option<Growth>,
}

/// What the tiler knew when it planned, for growing the tiles after the first batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Growth {
    /// The work bound the plan's side was cut to.
    pub work_bound: u64,
    /// Footprint of one tile of the plan's side, and the bytes a batch may hold.
    pub tile_bytes: u64,
    pub tile_binding: u64,
    pub batch_bytes: u64,
    pub largest_binding: u64,
}

/// Device seconds one tile's dispatches may take once the device's speed is measured: the work
/// bound counts every tap of the largest window (span paths do far less), so a tile of another
/// frame or aperture may run several times longer and still stay inside display watchdogs.
const TILE_SECONDS: f64 = 0.1;
/// Most the measured speed may raise the work bound over [`MAX_WORK_PER_TILE`].
const MAX_WORK_GROWTH: u64 = 64;

/// The work bound a device that did `work` in `device_ns` earns: [`TILE_SECONDS`] of it, between
/// `bound` (never lower) and [`MAX_WORK_GROWTH`] times [`MAX_WORK_PER_TILE`].
pub(crate) fn measured_work_bound(bound: u64, work: u64, device_ns: f64) -> u64 {
    if device_ns <= 0.0 || work == 0 {
        return bound;
    }
    let earned = work as f64 / (device_ns * 1e-9) * TILE_SECONDS;
    (earned.min((MAX_WORK_PER_TILE * MAX_WORK_GROWTH) as f64) as u64).max(bound)
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

/// The device bytes a render of `frame` may plan with: the driver's budget ([`planning_bytes`]),
/// within the memory cap less what the frame holds on the host. The cap is `--max-memory`, else
/// on a CPU device (its memory is the host's) [`CPU_DEVICE_MEMORY_FACTOR`] times the input,
/// leaving tiles at least [`MIN_DEFAULT_TILE_BYTES`].
fn device_bytes(driver: u64, cpu_device: bool, frame: &FrameTiling, options: &RenderOptions) -> Result<u64> {
    let tiles = match options.max_memory {
        Some(cap) if cap <= frame.host_bytes => {
            return Err(Error::invalid("max memory", format!(
                "the memory cap (RenderOptions::max_memory; --max-memory on the command line) of {} is less than the {} the frame's input and output take (host and device)",
                size(cap),
                size(frame.host_bytes)
            )))
        }
        Some(cap) => cap - frame.host_bytes,
        None if cpu_device => {
            (CPU_DEVICE_MEMORY_FACTOR * frame.input_bytes).saturating_sub(frame.host_bytes).max(MIN_DEFAULT_TILE_BYTES)
        }
        None => return Ok(driver),
    };
    Ok(driver.min(tiles))
}

/// `bytes` in MiB, or in bytes under one MiB.
fn size(bytes: u64) -> String {
    match bytes {
        b if b < 1 << 20 => format!("{b} bytes"),
        b => format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64),
    }
}

/// Runs `attempt` with the options' tile side and batch size, or else those planned from the
/// device's limits and memory budget; while it runs out of device memory, again with tiles
/// half as large (and no more per batch), then fewer tiles per batch. Fails with
/// [`Error::OutOfDeviceMemory`] when one smallest tile alone does not fit.
pub(crate) fn run_tiled<T>(
    ctx: &Context,
    frame: &FrameTiling,
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
        bytes: device_bytes(planning_bytes(ctx.memory_budget()), info.kind == "CPU", frame, options)?,
        // A GPU's bound starts where earlier renders on this context measured it.
        max_tile_work: match options.max_tile_work {
            Some(work) => work,
            None if info.kind == "CPU" => u64::MAX,
            None => ctx.learned_tile_work().max(MAX_WORK_PER_TILE),
        },
    };
    // The pool keeps buffers between tiles and renders within what this render may hold, and
    // the eighth its size classes may round the tiles' buffers up by.
    ctx.keep_buffers_within(limits.bytes.saturating_add(limits.bytes / 8));
    // Never more per batch than the frame has tiles: a retry then starts from what really ran.
    let tiles_per_batch = |tile: usize| {
        let wanted = match options.tiles_per_batch {
            Some(n) => n.max(1),
            None => limits.tiles_per_batch(footprint(tile)),
        };
        wanted.min(frame.width.div_ceil(tile) * frame.height.div_ceil(tile)).max(1)
    };
    let tile = match options.tile {
        Some(tile) => frame.round(tile),
        None => limits.tile_size(frame, &footprint),
    };
    let growth = if options.tile.is_none() { limits.growth(frame, tile, &footprint) } else { None };
    let mut plan = TilePlan { tile, tiles_per_batch: tiles_per_batch(tile), growth };
    loop {
        match attempt(plan) {
            // Drivers report a budget they cannot always honour: retry smaller.
            Err(error) if error.is_out_of_memory() => {
                let Some(smaller) = plan.smaller(frame, tiles_per_batch) else {
                    return Err(Error::OutOfDeviceMemory { tile: plan.tile, source: Box::new(error) });
                };
                log::warn!(
                    "out of device memory with {} px tiles, {} per submission; retrying with {} px, {} per submission",
                    plan.tile,
                    plan.tiles_per_batch,
                    smaller.tile,
                    smaller.tiles_per_batch
                );
                // Tiles grown from a measured speed are not tried again.
                plan = TilePlan { growth: None, ..smaller };
            }
            result => return result,
        }
    }
}

impl TilePlan {
    /// The next plan after running out of memory: half the tile side with at most as many
    /// tiles per batch (about a quarter of the memory); at the smallest tile, half the tiles
    /// per batch.
    fn smaller(self, frame: &FrameTiling, tiles_per_batch: impl Fn(usize) -> usize) -> Option<TilePlan> {
        if self.tile > frame.min_tile() {
            let tile = frame.round(self.tile / 2).max(frame.min_tile());
            Some(TilePlan { tile, tiles_per_batch: self.tiles_per_batch.min(tiles_per_batch(tile)), growth: None })
        } else if self.tiles_per_batch > 1 {
            Some(TilePlan { tile: self.tile, tiles_per_batch: self.tiles_per_batch / 2, growth: None })
        } else {
            None
        }
    }
}

/// What a plan must respect on this device.
struct Limits {
    /// Bytes of the largest buffer: the storage-buffer range and the largest allocation.
    largest_binding: u64,
    /// Bytes a batch may hold ([`device_bytes`]).
    bytes: u64,
    /// Work one tile may do ([`MAX_WORK_PER_TILE`] on a GPU).
    max_tile_work: u64,
}

impl Limits {
    fn fits(&self, footprint: Footprint, bytes: u64) -> bool {
        footprint.largest_binding <= self.largest_binding && footprint.total <= bytes
    }

    /// The largest tile (a multiple of the alignment) within the work bound; of those, the
    /// whole frame if it fits as one tile, else the largest of which [`MIN_TILES_PER_BATCH`]
    /// fit together, so batches hold several tiles.
    fn tile_size(&self, frame: &FrameTiling, footprint: &impl Fn(usize) -> Footprint) -> usize {
        let mut tile = frame.round(frame.width.max(frame.height));
        while tile > frame.min_tile() && frame.work(tile) > self.max_tile_work {
            tile = frame.shrink(tile);
        }
        if self.fits(footprint(tile), self.bytes) {
            return tile;
        }
        while tile > frame.min_tile() && !self.fits(footprint(tile), self.bytes / MIN_TILES_PER_BATCH) {
            tile = frame.shrink(tile);
        }
        tile
    }

    /// What a plan of `tile`-sided tiles needs to grow after its first batch, where the work
    /// bound (a GPU's) cut the frame and one tile fits the budget; `None` elsewhere (a CPU
    /// device, a frame the bound does not cut, tiles cut by memory alone).
    fn growth(&self, frame: &FrameTiling, tile: usize, footprint: &impl Fn(usize) -> Footprint) -> Option<Growth> {
        let whole = frame.round(frame.width.max(frame.height));
        let cut_by_work = self.max_tile_work != u64::MAX && frame.work(whole) > self.max_tile_work;
        (cut_by_work && self.fits(footprint(tile), self.bytes)).then(|| Growth {
            work_bound: self.max_tile_work,
            tile_bytes: footprint(tile).total,
            tile_binding: footprint(tile).largest_binding,
            batch_bytes: self.bytes,
            largest_binding: self.largest_binding,
        })
    }

    /// As many tiles as fit the budget together, at least one, at most [`MAX_TILES_PER_BATCH`].
    fn tiles_per_batch(&self, footprint: Footprint) -> usize {
        let fitting = self.bytes / footprint.total.max(1);
        (fitting as usize).clamp(1, MAX_TILES_PER_BATCH)
    }
}

/// Renders the frame's `plan.tile`-sided cores in batches of `plan.tiles_per_batch`: `record`
/// allocates a tile's buffers and records its passes into the batch, returning what to read
/// back; after the batch's one submission has completed, `collect` takes each tile's read-back
/// in order, and progress is reported per tile. The batch is reused: its command and descriptor
/// pools and staging arenas are reset after each submission, and a tile's buffers go back to the
/// device's pool once its batch is collected, for the next batch's tiles. Where the plan allows growth, the first batch's device time measures
/// the device, and the rest of the frame is cut into tiles as large as that speed allows
/// ([`measured_work_bound`], remembered by the context for later renders): on a fast GPU the
/// conservative first bound would cut an 8K frame into hundreds of tiles, each paying
/// allocations, uploads of its halo and a share of a submission. Returns the stats (`taps` left
/// to the caller) and the cores rendered, in order.
pub(crate) fn run_batches<T>(
    ctx: &Context,
    frame: &FrameTiling,
    plan: TilePlan,
    options: &RenderOptions,
    mut record: impl FnMut(&mut CommandBatch, Rect) -> Result<T>,
    mut collect: impl FnMut(Rect, T) -> Result<()>,
) -> Result<(RenderStats, Vec<Rect>)> {
    // Buffers in use, not allocated: the pool's idle buffers are no tile's.
    let baseline = ctx.buffer_bytes_in_use();
    let mut cores = frame.cores(plan.tile);
    let mut stats = RenderStats {
        device_ns: Some(0.0),
        tiles: cores.len(),
        tile_size: plan.tile,
        tiles_per_batch: plan.tiles_per_batch,
        ..RenderStats::default()
    };
    let mut batch = CommandBatch::new(ctx)?;
    let (mut done, mut growth) = (0, plan.growth);
    while done < cores.len() {
        let batch_cores: Vec<Rect> = cores[done..(done + stats.tiles_per_batch.max(1)).min(cores.len())].to_vec();
        let mut tiles = Vec::with_capacity(batch_cores.len());
        let recording = std::time::Instant::now();
        for &core in &batch_cores {
            tiles.push((core, record(&mut batch, core)?));
            let held = ctx.buffer_bytes_in_use().saturating_sub(baseline);
            if options.device_memory_limit.is_some_and(|limit| held > limit) {
                // The testing aid: as if the driver had refused the allocation just made.
                return Err(Error::Allocation(gpu_allocator::AllocationError::OutOfMemory));
            }
            stats.peak_device_bytes = stats.peak_device_bytes.max(held);
        }
        let waiting = std::time::Instant::now();
        stats.host_record_ns += (waiting - recording).as_nanos() as f64;
        batch.submit_and_wait()?;
        let collecting = std::time::Instant::now();
        stats.host_wait_ns += (collecting - waiting).as_nanos() as f64;
        stats.device_ns = stats.device_ns.zip(batch.last_device_time_ns()).map(|(a, b)| a + b);
        for (core, tile) in tiles {
            collect(core, tile)?;
            done += 1;
            if let Some(progress) = options.progress {
                progress(done, cores.len());
            }
        }
        stats.host_collect_ns += collecting.elapsed().as_nanos() as f64;
        if let (Some(g), Some(device_ns)) = (growth.take(), batch.last_device_time_ns()) {
            let work = batch_cores.iter().map(|c| c.area() as u64 * frame.work_per_pixel).sum();
            let bound = measured_work_bound(g.work_bound, work, device_ns);
            ctx.learn_tile_work(bound);
            if let Some(mut grown) = grown_plan(frame, plan.tile, &g, bound) {
                // The caller's batch size holds for the grown tiles too.
                grown.tiles_per_batch = options.tiles_per_batch.map_or(grown.tiles_per_batch, |n| n.max(1));
                if let Some(rest) = remaining_regions(frame, &cores[..done], plan.tile) {
                    cores.truncate(done);
                    cores.extend(rest.into_iter().flat_map(|region| frame.cores_in(region, grown.tile)));
                    (stats.tiles, stats.tile_size, stats.tiles_per_batch) =
                        (cores.len(), grown.tile, grown.tiles_per_batch);
                }
            }
        }
    }
    Ok((stats, cores))
}

/// The larger tiles a work bound of `bound` allows after a first batch of `tile`-sided ones:
/// the largest aligned side within the bound whose footprint (scaled from the first side's by
/// area, an over-estimate: the halo's share shrinks) fits the batch budget and the largest
/// binding; `None` unless it is at least twice the side.
fn grown_plan(frame: &FrameTiling, tile: usize, g: &Growth, bound: u64) -> Option<TilePlan> {
    let scale = |side: usize| ((side * side) as f64 / (tile * tile) as f64).max(1.0);
    let fits = |side: usize| {
        let s = scale(side);
        (g.tile_bytes as f64 * s) <= g.batch_bytes as f64 && (g.tile_binding as f64 * s) <= g.largest_binding as f64
    };
    let mut side = frame.round(frame.width.max(frame.height));
    while side > tile && (frame.work(side) > bound || !fits(side)) {
        side = frame.shrink(side);
    }
    if side < 2 * tile {
        return None;
    }
    let per_batch = (g.batch_bytes as f64 / (g.tile_bytes as f64 * scale(side))) as usize;
    Some(TilePlan { tile: side, tiles_per_batch: per_batch.clamp(1, MAX_TILES_PER_BATCH), growth: None })
}

/// The frame less the first cores of its `tile`-sided grid (row-major), as aligned rectangles:
/// the rest of their row of tiles and everything below it. `None` when the done cores span
/// more than one row of tiles.
fn remaining_regions(frame: &FrameTiling, done: &[Rect], tile: usize) -> Option<Vec<Rect>> {
    let last = done.last()?;
    if last.y0 != 0 {
        return None;
    }
    let strip = tile.min(frame.height);
    let regions = [
        Rect { x0: last.x1, y0: 0, x1: frame.width, y1: strip },
        Rect { x0: 0, y0: strip, x1: frame.width, y1: frame.height },
    ];
    Some(regions.into_iter().filter(|r| r.x1 > r.x0 && r.y1 > r.y0).collect())
}

/// The whole service for a method whose tiles each write one RGBA float32 pixel per core pixel
/// (core-local, row-major): plans, runs and retries as [`run_tiled`], reads each tile's core
/// into the frame. `record` gets the core and the read rect (the core grown by `halo(core)`,
/// clipped to the frame) and the room of the plan's largest tile ([`TileRoom`]), and returns the
/// tile's host-readable result ([`crate::vk::Buffer::readable_in`]).
pub(crate) fn render_image_tiles(
    ctx: &Context,
    frame: &FrameTiling,
    options: &RenderOptions,
    footprint: impl Fn(usize) -> Footprint,
    halo: impl Fn(Rect) -> usize,
    mut record: impl FnMut(&mut CommandBatch, Rect, Rect, TileRoom) -> Result<ReadBack>,
) -> Result<(Image, RenderStats)> {
    run_tiled(ctx, frame, options, footprint, |plan| {
        let mut image = Image::new(frame.width, frame.height);
        let max_halo = frame.cores(plan.tile).into_iter().map(&halo).max().unwrap_or(0);
        let room = TileRoom { core: frame.room(plan.tile, 0), read: frame.room(plan.tile, max_halo) };
        let record = |batch: &mut CommandBatch, core: Rect| {
            let read = core.grown(halo(core), frame.width, frame.height);
            record(batch, core, read, room)
        };
        let collect = |core: Rect, result: ReadBack| store_core(ctx, &mut image, core, &result);
        let (stats, _) = run_batches(ctx, frame, plan, options, record, collect)?;
        Ok((image, stats))
    })
}

/// Copies a tile's core-local RGBA result into the frame.
pub(crate) fn store_core(ctx: &Context, image: &mut Image, core: Rect, result: &ReadBack) -> Result<()> {
    let width = image.width;
    result.read_with(ctx, |result: &[[f32; 4]]| place_core_rows(&mut image.pixels, width, core, result))
}

/// Copies a core's rows (`rows`: `core.width()` items each, row-major) into their place in a
/// frame `width` items wide, row by row on every core: one thread's copy of a large core was
/// most of the collect time on a discrete GPU (171 ms of an H200's 4096^2 frame).
pub(crate) fn place_core_rows<T: Copy + Send + Sync>(frame: &mut [T], width: usize, core: Rect, rows: &[T]) {
    use rayon::prelude::*;
    let targets = frame.par_chunks_exact_mut(width).skip(core.y0).take(core.height());
    targets.zip(rows.par_chunks_exact(core.width())).for_each(|(row, from)| row[core.x0..core.x1].copy_from_slice(from));
}

/// Push-constant form of a tile: the core and read rects as (x, y, width, height), which the
/// tiled shaders (`glsl/common/tile.glsl`) take with the full frame size.
pub(crate) fn rect_push(rect: Rect) -> [i32; 4] {
    [rect.x0 as i32, rect.y0 as i32, rect.width() as i32, rect.height() as i32]
}

/// The pixels of `rect` from a row-major image `width` wide.
pub(crate) fn crop<T: Copy>(pixels: &[T], width: usize, rect: Rect) -> impl Iterator<Item = T> + '_ {
    crop_rows(pixels, width, rect).flat_map(|row| row.iter().copied())
}

/// The rows of `rect` in a row-major frame `width` wide, for uploads that copy whole rows.
pub(crate) fn crop_rows<T>(pixels: &[T], width: usize, rect: Rect) -> impl Iterator<Item = &[T]> + '_ {
    (rect.y0..rect.y1).map(move |y| &pixels[y * width + rect.x0..y * width + rect.x1])
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALIGN: usize = 16;

    fn frame(width: usize, height: usize) -> FrameTiling {
        FrameTiling::new(width, height, 1, ALIGN)
    }

    /// A footprint of `bytes_per_pixel` per core pixel (no halo), tiny bindings.
    fn per_pixel(bytes_per_pixel: u64) -> impl Fn(usize) -> Footprint {
        move |tile| Footprint { largest_binding: 1, total: (tile * tile) as u64 * bytes_per_pixel }
    }

    #[test]
    fn a_frame_that_fits_is_one_tile() {
        let limits = Limits { largest_binding: u64::MAX, bytes: 100 * 100, max_tile_work: u64::MAX };
        assert_eq!(limits.tile_size(&frame(90, 40), &per_pixel(1)), 96);
    }

    #[test]
    fn a_frame_that_does_not_fit_gets_tiles_of_which_two_fit_together() {
        // 1000x1000 at 1 byte a pixel in 300 kB: tiles must be at most 150 kB (387 px).
        let limits = Limits { largest_binding: u64::MAX, bytes: 300_000, max_tile_work: u64::MAX };
        let tile = limits.tile_size(&frame(1000, 1000), &per_pixel(1));
        assert_eq!(tile % ALIGN, 0);
        assert!((tile * tile) as u64 <= 150_000, "tile {tile}");
        // Shrinking by 3/4 steps lands within a factor 4/3 of the largest fitting side.
        assert!(tile * 4 / 3 + ALIGN > 387, "tile {tile} is needlessly small");
        assert_eq!(limits.tiles_per_batch(per_pixel(1)(tile)), 300_000 / (tile * tile));
        assert!(limits.tiles_per_batch(per_pixel(1)(tile)) >= 2);
    }

    #[test]
    fn unaligned_methods_get_any_tile_side() {
        let odd = FrameTiling::new(1000, 1000, 1, 1);
        assert_eq!(odd.round(37), 37);
        let limits = Limits { largest_binding: u64::MAX, bytes: 300_000, max_tile_work: u64::MAX };
        let tile = limits.tile_size(&odd, &per_pixel(1));
        assert!((tile * tile) as u64 <= 150_000 && tile * 4 / 3 + 1 > 387, "tile {tile}");
    }

    /// A budget that no tile fits ends at the smallest tile (where the batch then shrinks), even
    /// from sides where 3/4 rounds back up to the same multiple of the alignment.
    #[test]
    fn a_budget_no_tile_fits_ends_at_the_smallest_tile() {
        let limits = Limits { largest_binding: u64::MAX, bytes: 1, max_tile_work: u64::MAX };
        assert_eq!(limits.tile_size(&frame(1000, 1000), &per_pixel(1)), ALIGN);
        assert_eq!(limits.tile_size(&FrameTiling::new(1000, 1000, 1, 1), &per_pixel(1)), MIN_TILE);
    }

    /// On a GPU a tile's dispatch stays within the work bound (the display watchdog) whatever
    /// the memory: 512 lens samples of 8 steps at 8K come in tiles of at most 2e9 steps.
    #[test]
    fn the_work_bound_cuts_heavy_frames_that_memory_would_leave_whole() {
        let limits = Limits { largest_binding: u64::MAX, bytes: u64::MAX, max_tile_work: MAX_WORK_PER_TILE };
        let heavy = FrameTiling::new(7680, 4320, 1, 1).with_work(512 * 8);
        let tile = limits.tile_size(&heavy, &per_pixel(1));
        assert!(
            heavy.work(tile) <= MAX_WORK_PER_TILE && heavy.work(tile * 4 / 3 + 1) > MAX_WORK_PER_TILE,
            "tile {tile}"
        );
        let light = FrameTiling::new(7680, 4320, 1, 1).with_work(1);
        assert_eq!(limits.tile_size(&light, &per_pixel(1)), 7680, "light work stays one tile");
    }

    #[test]
    fn the_storage_range_bounds_the_tile_whatever_the_memory() {
        let limits = Limits { largest_binding: 64 * 64, bytes: u64::MAX, max_tile_work: u64::MAX };
        let binding = |tile: usize| Footprint { largest_binding: (tile * tile) as u64, total: 0 };
        assert_eq!(limits.tile_size(&frame(1000, 1000), &binding), 64);
    }

    #[test]
    fn tiles_per_batch_stays_between_one_and_the_cap() {
        let limits = Limits { largest_binding: u64::MAX, bytes: 1000, max_tile_work: u64::MAX };
        let footprint = |total| Footprint { largest_binding: 1, total };
        assert_eq!(limits.tiles_per_batch(footprint(5000)), 1, "a tile over the budget still runs alone");
        assert_eq!(limits.tiles_per_batch(footprint(400)), 2);
        assert_eq!(limits.tiles_per_batch(footprint(1)), MAX_TILES_PER_BATCH);
    }

    #[test]
    fn out_of_memory_halves_the_tile_then_the_batch_then_gives_up() {
        let f = frame(1000, 1000);
        let plan = TilePlan { tile: 96, tiles_per_batch: 4, growth: None };
        let next = plan.smaller(&f, |_| 8).unwrap();
        assert_eq!(
            next,
            TilePlan { tile: 48, tiles_per_batch: 4, growth: None },
            "never more tiles per batch after a failure"
        );
        assert_eq!(
            next.smaller(&f, |_| 3).unwrap(),
            TilePlan { tile: 32, tiles_per_batch: 3, growth: None },
            "24 rounds up to 32"
        );
        let smallest = TilePlan { tile: ALIGN, tiles_per_batch: 3, growth: None };
        assert_eq!(smallest.smaller(&f, |_| 8), Some(TilePlan { tile: ALIGN, tiles_per_batch: 1, growth: None }));
        assert_eq!(TilePlan { tile: ALIGN, tiles_per_batch: 1, growth: None }.smaller(&f, |_| 8), None);
    }

    #[test]
    fn plans_leave_headroom_and_trust_the_driver_budget_more_than_the_heap_size() {
        let driver = planning_bytes(MemoryBudget { available_bytes: 1 << 30, measured: true });
        let heap = planning_bytes(MemoryBudget { available_bytes: 1 << 30, measured: false });
        assert!(heap < driver && driver < 1 << 30, "heap {heap}, driver {driver}");
    }

    /// A CPU device plans within 3x the input less what the host holds, however much memory
    /// the system offers; `--max-memory` replaces that bound, and one below the host's share
    /// is refused with the numbers.
    #[test]
    fn cpu_devices_plan_from_the_frame_not_from_free_memory() {
        let f = FrameTiling::new(4096, 2304, 2, 16);
        let plenty = 64 << 30;
        let default = device_bytes(plenty, true, &f, &RenderOptions::default()).unwrap();
        assert_eq!(default, 3 * f.input_bytes - f.host_bytes);
        assert_eq!(
            device_bytes(plenty, false, &f, &RenderOptions::default()).unwrap(),
            plenty,
            "a GPU keeps the driver's budget"
        );
        let capped = RenderOptions { max_memory: Some(f.host_bytes + (100 << 20)), ..RenderOptions::default() };
        assert_eq!(device_bytes(plenty, false, &f, &capped).unwrap(), 100 << 20);
        assert_eq!(device_bytes(1 << 20, true, &f, &capped).unwrap(), 1 << 20, "the driver's budget still bounds it");
        let mut heavy = f;
        heavy.host_bytes = 3 * f.input_bytes;
        assert_eq!(
            device_bytes(plenty, true, &heavy, &RenderOptions::default()).unwrap(),
            MIN_DEFAULT_TILE_BYTES,
            "tiles keep a floor"
        );
        let too_small = RenderOptions { max_memory: Some(f.host_bytes / 2), ..RenderOptions::default() };
        let error = device_bytes(plenty, true, &f, &too_small).unwrap_err().to_string();
        assert!(error.contains("--max-memory") && error.contains("of 252.0 MiB is less than the 504.0 MiB"), "{error}");
    }

    #[test]
    fn cores_cover_the_frame_once_with_odd_tiles() {
        let f = FrameTiling::new(45, 37, 1, 1);
        for tile in [1, 7, 13, 45, 64] {
            let mut covered = vec![0u8; 45 * 37];
            for core in f.cores(tile) {
                for y in core.y0..core.y1 {
                    for x in core.x0..core.x1 {
                        covered[y * 45 + x] += 1;
                    }
                }
            }
            assert!(covered.iter().all(|&c| c == 1), "tile {tile}");
        }
    }

    /// After the first batch of a row of tiles, the rest of that row and the rows below cover
    /// the frame exactly once with the grown side, aligned.
    #[test]
    fn remaining_regions_and_grown_cores_cover_the_rest_once() {
        let f = FrameTiling::new(300, 200, 1, ALIGN);
        let first = f.cores(32);
        for done in [1, 3, 10] {
            let rest = remaining_regions(&f, &first[..done], 32).expect("within the first row");
            let mut covered = vec![0u8; 300 * 200];
            let grown = rest.iter().flat_map(|&r| f.cores_in(r, 96));
            for core in first[..done].iter().copied().chain(grown) {
                assert!(core.x0 % ALIGN == 0 && core.y0 % ALIGN == 0, "{core:?}");
                for y in core.y0..core.y1 {
                    for x in core.x0..core.x1 {
                        covered[y * 300 + x] += 1;
                    }
                }
            }
            assert!(covered.iter().all(|&c| c == 1), "{done} done");
        }
        assert!(remaining_regions(&f, &first[..11], 32).is_none(), "a second row of done tiles is not regrown");
    }

    /// Growth is offered wherever the work bound cut the frame, also when the side it settled on
    /// is a 3/4 step below the bound (one alignment step larger would still fit it), and not on
    /// a CPU device, nor for a frame the bound leaves whole.
    #[test]
    fn growth_is_offered_where_the_work_bound_cut_the_frame() {
        let f = FrameTiling::new(4096, 4096, 1, ALIGN).with_work(100);
        let gpu = Limits { largest_binding: u64::MAX, bytes: u64::MAX / 4, max_tile_work: 100 * 300 * 300 };
        let tile = gpu.tile_size(&f, &per_pixel(4));
        assert!(f.work(f.round(tile + 1)) <= gpu.max_tile_work, "the case of a side below the bound: {tile}");
        let growth = gpu.growth(&f, tile, &per_pixel(4)).expect("the bound cut the frame");
        assert_eq!((growth.work_bound, growth.tile_bytes), (gpu.max_tile_work, (tile * tile) as u64 * 4));
        let cpu = Limits { max_tile_work: u64::MAX, ..gpu };
        assert!(cpu.growth(&f, cpu.tile_size(&f, &per_pixel(4)), &per_pixel(4)).is_none());
        let small = FrameTiling::new(64, 64, 1, ALIGN).with_work(100);
        assert!(gpu.growth(&small, gpu.tile_size(&small, &per_pixel(4)), &per_pixel(4)).is_none(), "one tile");
    }

    /// The measured bound is the device's speed times TILE_SECONDS, never below the bound it
    /// measured under nor above MAX_WORK_GROWTH times the default; the grown side keeps both the
    /// bound and the memory budget, or is refused when not twice the side.
    #[test]
    fn grown_tiles_respect_the_measured_bound_and_the_budget() {
        assert_eq!(measured_work_bound(100, 1_000, 1e6), 100_000, "1e9 work/s for 0.1 s");
        assert_eq!(measured_work_bound(200_000, 1_000, 1e6), 200_000);
        assert_eq!(measured_work_bound(100, u64::MAX / 2, 1.0), MAX_WORK_PER_TILE * MAX_WORK_GROWTH);
        let f = FrameTiling::new(4096, 4096, 1, ALIGN).with_work(100);
        let g = Growth {
            work_bound: 100 * 64 * 64,
            tile_bytes: 64 * 64 * 10,
            tile_binding: 1,
            batch_bytes: u64::MAX / 4,
            largest_binding: u64::MAX / 4,
        };
        let grown = grown_plan(&f, 64, &g, 100 * 512 * 512).expect("grows");
        // The sides are tried in 3/4 steps from the frame's, as the first plan's are.
        assert!(f.work(grown.tile) <= 100 * 512 * 512 && grown.tile * 4 / 3 > 512, "{grown:?}");
        let tight = Growth { batch_bytes: 256 * 256 * 10, ..g };
        let grown = grown_plan(&f, 64, &tight, 100 * 512 * 512).expect("grows within memory");
        assert!(grown.tile <= 256 && grown.tile >= 128 && grown.tiles_per_batch == 1, "{grown:?}");
        assert!(grown_plan(&f, 64, &g, 100 * 100 * 100).is_none(), "less than twice the side");
    }
}
