//! A uniform grid over axis-aligned boxes: a point is tested only against the items whose box
//! overlaps its cell. Used by the cut-out shapes with many parts (strokes, unions of leaves),
//! which dominated the ray tracer's time when scanned linearly.

/// Cells of `1 / inverse_size` texture units from `min`; cell `c` lists
/// `indices[offsets[c]..offsets[c + 1]]`.
#[derive(Debug)]
pub struct Grid {
    min: [f32; 2],
    cells: [usize; 2],
    inverse_size: [f32; 2],
    offsets: Vec<u32>,
    indices: Vec<u32>,
}

impl Grid {
    /// Grid over `boxes` (`(lo, hi)` corners) inside `[min, max]`; about two cells per item
    /// along each axis, at most 256, so lists stay a few entries long.
    pub fn new(boxes: &[([f32; 2], [f32; 2])], min: [f32; 2], max: [f32; 2]) -> Self {
        let side = ((boxes.len() as f32).sqrt() * 2.0).ceil().clamp(1.0, 256.0) as usize;
        let extent = [(max[0] - min[0]).max(f32::MIN_POSITIVE), (max[1] - min[1]).max(f32::MIN_POSITIVE)];
        let mut grid = Grid { min, cells: [side; 2], inverse_size: [side as f32 / extent[0], side as f32 / extent[1]], offsets: vec![0], indices: Vec::new() };
        let mut lists = vec![Vec::new(); side * side];
        for (i, (lo, hi)) in boxes.iter().enumerate() {
            // The lookup's own (monotonic) cell mapping: a point inside the box maps to a cell
            // between those of the box corners, so no covering item is ever missed.
            let (c0, c1) = (grid.cell_of(*lo), grid.cell_of(*hi));
            for cy in c0[1]..=c1[1] {
                for cx in c0[0]..=c1[0] {
                    lists[cy * side + cx].push(i as u32);
                }
            }
        }
        for list in lists {
            grid.indices.extend(list);
            grid.offsets.push(grid.indices.len() as u32);
        }
        grid
    }

    #[inline]
    fn cell_of(&self, p: [f32; 2]) -> [usize; 2] {
        let axis = |a: usize| (((p[a] - self.min[a]) * self.inverse_size[a]).floor().max(0.0) as usize).min(self.cells[a] - 1);
        [axis(0), axis(1)]
    }

    /// Indices of the items whose box may contain `p`.
    #[inline]
    pub fn candidates(&self, p: [f32; 2]) -> &[u32] {
        let [cx, cy] = self.cell_of(p);
        let c = cy * self.cells[0] + cx;
        &self.indices[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }
}
