//! Push-pull hole filling (Gortler et al. 1996): weighted averages down an image pyramid,
//! then each finer level takes the coarse value wherever its own weight is missing. Used to
//! define depth under transparent pixels and to fill hidden background behind cut layers.
//! It is smooth, has no parameters to tune, and never invents values outside the range of
//! the known samples (every output is a convex combination of them).

struct Level<const N: usize> {
    width: usize,
    height: usize,
    values: Vec<[f32; N]>,
    weights: Vec<f32>,
}

fn pull<const N: usize>(fine: &Level<N>) -> Level<N> {
    let (width, height) = (fine.width.div_ceil(2), fine.height.div_ceil(2));
    let mut values = vec![[0.0; N]; width * height];
    let mut weights = vec![0.0; width * height];
    for y in 0..height {
        for x in 0..width {
            let (mut sum, mut total) = ([0.0f32; N], 0.0f32);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (fx, fy) = (2 * x + dx, 2 * y + dy);
                if fx < fine.width && fy < fine.height {
                    let i = fy * fine.width + fx;
                    let w = fine.weights[i];
                    if w <= 0.0 {
                        continue; // its value is undefined (may be NaN or infinite)
                    }
                    total += w;
                    for (s, v) in sum.iter_mut().zip(fine.values[i]) {
                        *s += w * v;
                    }
                }
            }
            if total > 0.0 {
                values[y * width + x] = sum.map(|s| s / total);
            }
            weights[y * width + x] = total.min(1.0);
        }
    }
    Level { width, height, values, weights }
}

/// Bilinear sample of a coarse level at the centre of fine pixel (x, y), using only
/// coarse pixels that carry weight (so empty regions do not pull values towards zero).
fn sample_coarse<const N: usize>(coarse: &Level<N>, x: usize, y: usize) -> [f32; N] {
    let cx = (x as f32 + 0.5) * 0.5 - 0.5;
    let cy = (y as f32 + 0.5) * 0.5 - 0.5;
    let (x0, y0) = (cx.floor(), cy.floor());
    let (tx, ty) = (cx - x0, cy - y0);
    let (mut sum, mut total) = ([0.0f32; N], 0.0f32);
    for (dx, dy, w) in
        [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)]
    {
        let xi = (x0 as i64 + dx).clamp(0, coarse.width as i64 - 1) as usize;
        let yi = (y0 as i64 + dy).clamp(0, coarse.height as i64 - 1) as usize;
        let i = yi * coarse.width + xi;
        let w = w * coarse.weights[i];
        if w <= 0.0 {
            continue;
        }
        total += w;
        for (s, v) in sum.iter_mut().zip(coarse.values[i]) {
            *s += w * v;
        }
    }
    if total > 0.0 {
        sum.map(|s| s / total)
    } else {
        coarse.values[(y0.max(0.0) as usize).min(coarse.height - 1) * coarse.width
            + (x0.max(0.0) as usize).min(coarse.width - 1)]
    }
}

fn push<const N: usize>(fine: &mut Level<N>, coarse: &Level<N>) {
    for y in 0..fine.height {
        for x in 0..fine.width {
            let i = y * fine.width + x;
            let w = fine.weights[i].clamp(0.0, 1.0);
            if w < 1.0 {
                let c = sample_coarse(coarse, x, y);
                for (v, c) in fine.values[i].iter_mut().zip(c) {
                    let own = if w > 0.0 { w * *v } else { 0.0 };
                    *v = own + (1.0 - w) * c;
                }
                fine.weights[i] = 1.0;
            }
        }
    }
}

/// Replaces `values` wherever `weights` is 0 by a smooth weighted extension of the pixels
/// with positive weight; those keep their value exactly. Returns false (and changes
/// nothing) when no pixel has weight.
pub fn push_pull<const N: usize>(width: usize, height: usize, values: &mut [[f32; N]], weights: &[f32]) -> bool {
    assert_eq!(values.len(), width * height);
    assert_eq!(weights.len(), width * height);
    if width == 0 || height == 0 || !weights.iter().any(|&w| w > 0.0) {
        return false;
    }
    let base = Level { width, height, values: values.to_vec(), weights: weights.iter().map(|w| w.max(0.0)).collect() };
    let mut levels = vec![base];
    while levels.last().is_some_and(|l| l.width > 1 || l.height > 1) {
        let next = pull(levels.last().expect("pyramid has a level"));
        levels.push(next);
    }
    for k in (1..levels.len()).rev() {
        let (finer, coarser) = levels.split_at_mut(k);
        push(&mut finer[k - 1], &coarser[0]);
    }
    for (i, v) in values.iter_mut().enumerate() {
        if weights[i] <= 0.0 {
            *v = levels[0].values[i];
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_pixels_are_kept_and_holes_stay_in_range() {
        let (w, h) = (13, 9);
        let mut values: Vec<[f32; 1]> = (0..w * h).map(|i| [(i % w) as f32]).collect();
        let weights: Vec<f32> = (0..w * h).map(|i| if (i % w) < 4 || (i % w) > 9 { 1.0 } else { 0.0 }).collect();
        let original = values.clone();
        for (i, v) in values.iter_mut().enumerate() {
            if weights[i] == 0.0 {
                v[0] = f32::NAN;
            }
        }
        assert!(push_pull(w, h, &mut values, &weights));
        for i in 0..w * h {
            if weights[i] > 0.0 {
                assert_eq!(values[i], original[i]);
            } else {
                // Convex combinations of the known x = 0..3 and 10..12 columns.
                assert!(values[i][0] >= 0.0 && values[i][0] <= 12.0, "{:?}", values[i]);
            }
        }
    }

    #[test]
    fn constant_known_values_fill_with_that_constant() {
        let (w, h) = (8, 8);
        let mut values = vec![[0.0f32, 0.0]; w * h];
        let mut weights = vec![0.0f32; w * h];
        values[0] = [3.0, -1.0];
        weights[0] = 0.5;
        assert!(push_pull(w, h, &mut values, &weights));
        for v in &values {
            assert!((v[0] - 3.0).abs() < 1e-5 && (v[1] + 1.0).abs() < 1e-5, "{v:?}");
        }
    }
}
