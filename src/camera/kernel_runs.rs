//! Row runs of a kernel image: the table that lets the kernel path of a gather sum whole runs
//! of full-weight taps and skip runs of zero-weight ones, evaluating the kernel only at the
//! taps in between (`glsl/common/drbokeh_layer.glsl`, `DRBOKEH_LAYER_KERNEL`).
//!
//! [`KernelImage::sample`] is bilinear: at a point of texel cell `(i, j)` (between texel
//! centres `i, i + 1` and `j, j + 1`; texels outside the image are 0) it blends the cell's
//! four corners, so it is 1 wherever all four are 1 (up to the f32 rounding of the blend) and
//! exactly 0 wherever all four are 0. Cells are *full*, *zero* or *partial* by their corners.
//! A gather row at height v crosses one or two cell rows over the range of scales a tile sees,
//! so the table holds, for every cell row and every pair of adjacent ones, the runs of cells
//! that are full (resp. zero) in all of them, as u intervals of the unit kernel ([-1, 1]^2),
//! shrunk by [`SLACK`] for the f32 rounding of `o / c`.
use super::aperture::KernelImage;

/// Inward slack of every run, in unit-kernel units: far above the f32 rounding of a tap's
/// kernel coordinate (~1e-7), far below a cell (2 / 64 for a 64^2 kernel).
const SLACK: f32 = 1e-5;

/// Class of a run in the table (`.z` of a run texel): full weight or exact zero.
pub const KERNEL_RUN_FULL: f32 = 1.0;
pub const KERNEL_RUN_ZERO: f32 = 2.0;

/// The table, as texels: `[0]` = (n, first texel of the cells, 0, 0); then one index texel per row set, `(first, count,
/// 0, 0)` with `first` the texel of its first run: set `s` in `0..n + 1` is the single cell row
/// `j = s - 1` (cell rows run from -1 to n - 1), set `n + 1 + s` in `0..n` the pair `(s - 1,
/// s)`; then the runs, `(u_lo, u_hi, class, 0)`, in ascending u. A zero run at either end
/// reaches past the kernel (`-/+ 2`: the sample is 0 outside it). Last, the kernel's cells
/// `(i, j)` for i, j in -1..=n, row-major (`n + 2` a side): each texel the cell's four corners
/// (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1), zero outside the image, so the shader samples
/// with one fetch and no bounds tests (`kernel_runs_sample`).
pub fn kernel_run_table(kernel: &KernelImage) -> Vec<[f32; 4]> {
    let n = kernel.size as i64;
    let texel = |x: i64, y: i64| if x < 0 || y < 0 || x >= n || y >= n { 0.0 } else { kernel.weights[(y * n + x) as usize] };
    // Class of cell (i, j): 1 full, 2 zero, 0 partial.
    let cell = |i: i64, j: i64| {
        let corners = [texel(i, j), texel(i + 1, j), texel(i, j + 1), texel(i + 1, j + 1)];
        if corners.iter().all(|&w| w == 1.0) {
            KERNEL_RUN_FULL
        } else if corners.iter().all(|&w| w == 0.0) {
            KERNEL_RUN_ZERO
        } else {
            0.0
        }
    };
    let row_sets: Vec<Vec<i64>> = (-1..n).map(|j| vec![j]).chain((-1..n - 1).map(|j| vec![j, j + 1])).collect();
    let mut index = Vec::with_capacity(row_sets.len());
    let mut runs = Vec::new();
    let first = 1 + row_sets.len();
    // Cell i spans u in [(2 i + 1) / n - 1, (2 i + 3) / n - 1].
    let u = |i: i64| (2 * i + 1) as f32 / n as f32 - 1.0;
    for rows in &row_sets {
        let start = runs.len();
        let class = |i: i64| {
            let classes: Vec<f32> = rows.iter().map(|&j| cell(i, j)).collect();
            if classes.iter().all(|&c| c == classes[0]) { classes[0] } else { 0.0 }
        };
        let mut i = -1;
        while i < n {
            let c = class(i);
            let mut end = i;
            while end + 1 < n && class(end + 1) == c {
                end += 1;
            }
            if c != 0.0 {
                let lo = if i == -1 && c == KERNEL_RUN_ZERO { -2.0 } else { u(i) + SLACK };
                let hi = if end == n - 1 && c == KERNEL_RUN_ZERO { 2.0 } else { u(end + 1) - SLACK };
                runs.push([lo, hi, c, 0.0]);
            }
            i = end + 1;
        }
        index.push([(first + start) as f32, (runs.len() - start) as f32, 0.0, 0.0]);
    }
    let padded = (first + runs.len()) as f32;
    let side = n + 2;
    let cells = (0..side * side).map(|c| {
        let (i, j) = (c % side - 1, c / side - 1);
        [texel(i, j), texel(i + 1, j), texel(i, j + 1), texel(i + 1, j + 1)]
    });
    std::iter::once([n as f32, padded, 0.0, 0.0]).chain(index).chain(runs).chain(cells).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `kernel_runs_sample` (glsl/common/drbokeh_layer.glsl) on the table's cells, in f32.
    fn cells_sample(table: &[[f32; 4]], u: f32, v: f32) -> f32 {
        let (n, first) = (table[0][0], table[0][1] as usize);
        let fx = ((u * 0.5 + 0.5) * n - 0.5).clamp(-1.0, n);
        let fy = ((v * 0.5 + 0.5) * n - 0.5).clamp(-1.0, n);
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let c = table[first + (y0 as i64 + 1) as usize * (n as usize + 2) + (x0 as i64 + 1) as usize];
        let top = c[0] * (1.0 - tx) + c[1] * tx;
        let bottom = c[2] * (1.0 - tx) + c[3] * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// The cells sample every point, inside the kernel, on its edges and far outside, to the
    /// same bits as [`KernelImage::sample`] (same texels, same weights, same operations).
    #[test]
    fn cells_sample_as_the_kernel_does() {
        let kernel = KernelImage::from_weights(5, (0..25).map(|i| ((i * 7) % 11) as f32 / 10.0).collect()).unwrap();
        let table = kernel_run_table(&kernel);
        for a in -130..=130 {
            for b in -130..=130 {
                let (u, v) = (a as f32 / 97.0, b as f32 / 89.0);
                assert_eq!(cells_sample(&table, u, v).to_bits(), kernel.sample(u, v).to_bits(), "({u}, {v})");
            }
        }
    }

    /// Every point of a full run samples 1 and every point of a zero run 0, in every row of
    /// its set; a 2x2 kernel with one zero texel has both kinds and partial cells.
    #[test]
    fn runs_sample_as_their_class() {
        let kernel = KernelImage::from_weights(8, (0..64).map(|i| if (i % 8 + i / 8) % 7 == 3 { 0.0 } else if i % 8 < 5 && i / 8 > 1 { 1.0 } else { 0.5 }).collect()).unwrap();
        let table = kernel_run_table(&kernel);
        let n = table[0][0] as i64;
        let sets = (2 * n + 1) as usize;
        for set in 0..sets {
            let rows: Vec<i64> = if set <= n as usize { vec![set as i64 - 1] } else { vec![set as i64 - n - 2, set as i64 - n - 1] };
            let [first, count, ..] = table[1 + set];
            for run in &table[first as usize..(first + count) as usize] {
                for &j in &rows {
                    for step in 0..=50 {
                        let u = run[0].max(-1.2) + (run[1].min(1.2) - run[0].max(-1.2)) * step as f32 / 50.0;
                        for t in [0.0, 0.5, 1.0] {
                            // Heights inside cell row j: fy in [j, j + 1].
                            let fy = j as f32 + t;
                            let v = (2.0 * fy + 1.0) / n as f32 - 1.0;
                            let want = if run[2] == KERNEL_RUN_FULL { 1.0 } else { 0.0 };
                            let got = kernel.sample(u, v);
                            assert!((got - want).abs() < 1e-5, "set {set} run {run:?} at ({u}, {v}): {got}");
                        }
                    }
                }
            }
        }
    }
}
