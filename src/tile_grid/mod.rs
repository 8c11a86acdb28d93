//! The tile grid with halos (pure math, no Vulkan): big frames are rendered tile by tile, each
//! tile reading its core plus the halo its largest reachable CoC needs.
//!
//! Halos come from a max-radius pyramid (the N-buffer idea of Lee et al. 2009, with square
//! mip levels): `max_in(rect)` bounds the CoC of every source in a rectangle in O(1) levels.
//! A source `y` reaches a core pixel `x` only if `|x - y| <= r_y + margin`, so the halo is the
//! fixed point of `h = max r over (core grown by h + margin)`, reached in a few iterations.

/// A half-open pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct Rect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl Rect {
    pub fn width(&self) -> usize {
        self.x1 - self.x0
    }
    pub fn height(&self) -> usize {
        self.y1 - self.y0
    }
    pub fn area(&self) -> usize {
        self.width() * self.height()
    }
    /// Grown by `by` pixels on every side, clipped to a `width x height` image.
    pub fn grown(&self, by: usize, width: usize, height: usize) -> Rect {
        Rect {
            x0: self.x0.saturating_sub(by),
            y0: self.y0.saturating_sub(by),
            x1: (self.x1 + by).min(width),
            y1: (self.y1 + by).min(height),
        }
    }
}

/// Per-level block maxima of a per-pixel radius map; level `k` holds the max over
/// `2^k x 2^k` blocks.
pub struct MaxPyramid {
    width: usize,
    height: usize,
    levels: Vec<(usize, usize, Vec<f32>)>,
}

impl MaxPyramid {
    pub fn new(width: usize, height: usize, radius: &[f32]) -> Self {
        assert_eq!(radius.len(), width * height, "radius map size");
        let mut levels = vec![(width, height, radius.to_vec())];
        while let Some((w, h, data)) = levels.last().filter(|(w, h, _)| *w > 1 || *h > 1) {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let mut next = vec![0.0f32; nw * nh];
            for y in 0..*h {
                for x in 0..*w {
                    let slot = &mut next[(y / 2) * nw + x / 2];
                    *slot = slot.max(data[y * w + x]);
                }
            }
            levels.push((nw, nh, next));
        }
        Self { width, height, levels }
    }

    /// An upper bound of the radius over `rect` (exact on level-0; conservative above, since
    /// it uses the coarsest level whose blocks cover the rect with at most ~4x4 lookups).
    pub fn max_in(&self, rect: Rect) -> f32 {
        if rect.area() == 0 {
            return 0.0;
        }
        let extent = rect.width().max(rect.height());
        let level = (usize::BITS - extent.saturating_sub(1).leading_zeros()).saturating_sub(1) as usize;
        let level = level.min(self.levels.len() - 1);
        let (w, _, data) = &self.levels[level];
        let mut best = 0.0f32;
        for by in (rect.y0 >> level)..=((rect.y1 - 1) >> level) {
            for bx in (rect.x0 >> level)..=((rect.x1 - 1) >> level) {
                best = best.max(data[by * w + bx]);
            }
        }
        best
    }

    /// Halo (pixels) that `core` needs: every source within `r + margin` of the core is read.
    pub fn halo(&self, core: Rect, margin: f32) -> usize {
        let mut halo = 0usize;
        loop {
            let reach = self.max_in(core.grown(halo, self.width, self.height)) + margin;
            let needed = reach.max(0.0).ceil() as usize;
            if needed <= halo {
                return halo;
            }
            halo = needed;
        }
    }
}

/// One tile: the pixels it writes and the pixels it reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Tile {
    pub core: Rect,
    pub read: Rect,
}

/// Cuts a `width x height` frame into `tile x tile` cores (the last row/column smaller) and
/// gives each the read window its halo needs.
pub fn plan(width: usize, height: usize, tile: usize, pyramid: &MaxPyramid, margin: f32) -> Vec<Tile> {
    let tile = tile.max(1);
    let mut tiles = Vec::new();
    for y0 in (0..height).step_by(tile) {
        for x0 in (0..width).step_by(tile) {
            let core = Rect { x0, y0, x1: (x0 + tile).min(width), y1: (y0 + tile).min(height) };
            let halo = pyramid.halo(core, margin);
            tiles.push(Tile { core, read: core.grown(halo, width, height) });
        }
    }
    tiles
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_max(w: usize, r: &[f32], rect: Rect) -> f32 {
        let mut m = 0.0f32;
        for y in rect.y0..rect.y1 {
            for x in rect.x0..rect.x1 {
                m = m.max(r[y * w + x]);
            }
        }
        m
    }

    #[test]
    fn pyramid_max_is_an_upper_bound_and_exact_for_whole_image() {
        let (w, h) = (37, 29);
        let r: Vec<f32> = (0..w * h).map(|i| ((i * 7919) % 101) as f32 * 0.1).collect();
        let p = MaxPyramid::new(w, h, &r);
        let whole = Rect { x0: 0, y0: 0, x1: w, y1: h };
        assert_eq!(p.max_in(whole), brute_max(w, &r, whole));
        for (x0, y0, x1, y1) in [(0, 0, 1, 1), (3, 4, 20, 9), (30, 20, 37, 29), (5, 5, 6, 29)] {
            let rect = Rect { x0, y0, x1, y1 };
            assert!(p.max_in(rect) >= brute_max(w, &r, rect), "{rect:?}");
        }
        let single = Rect { x0: 10, y0: 10, x1: 11, y1: 11 };
        assert_eq!(p.max_in(single), r[10 * w + 10], "a single pixel is exact");
    }

    #[test]
    fn halo_covers_every_source_that_reaches_the_core() {
        // One far-away source with a large radius must enlarge the halo of the tile it reaches.
        let (w, h) = (200, 100);
        let mut r = vec![1.0f32; w * h];
        r[50 * w + 150] = 60.0; // reaches x >= 90
        let p = MaxPyramid::new(w, h, &r);
        let near = Rect { x0: 96, y0: 32, x1: 128, y1: 64 };
        assert!(near.grown(p.halo(near, 1.0), w, h).x1 > 150);
        // A tile out of its reach keeps a small halo (the pyramid's block bound may be coarse,
        // but not the 60 px of a source it cannot reach when the map is mostly 1 px).
        let far = Rect { x0: 0, y0: 0, x1: 16, y1: 16 };
        assert!(p.halo(far, 1.0) <= 2, "halo {}", p.halo(far, 1.0));
    }

    #[test]
    fn plan_covers_the_frame_exactly_once_with_sizes_that_do_not_divide() {
        let (w, h) = (100, 70);
        let p = MaxPyramid::new(w, h, &vec![3.0; w * h]);
        let tiles = plan(w, h, 32, &p, 1.0);
        let mut covered = vec![0u8; w * h];
        for t in &tiles {
            assert!(t.read.x0 <= t.core.x0 && t.read.x1 >= t.core.x1 && t.read.y0 <= t.core.y0 && t.read.y1 >= t.core.y1);
            for y in t.core.y0..t.core.y1 {
                for x in t.core.x0..t.core.x1 {
                    covered[y * w + x] += 1;
                }
            }
        }
        assert!(covered.iter().all(|&c| c == 1));
        assert_eq!(tiles.len(), 4 * 3);
    }
}
