//! A literal, independent evaluation of the authors' released formulas (DESIGN.md "Facts from
//! the released CUDA code"), written as the released code is organised: each source scatters
//! into a fixed square window of half-width `lens_size`, disk aperture only, no tail cut.
//! Shares no code with the renderer, so `compat_equals_released_formulas` checks the
//! renderer's compat path (window bounds, loop structure, term plumbing) against it.
use crate::camera::CocModel;
use crate::stack::LayerStack;

pub fn render_released(stack: &LayerStack, coc: &CocModel, lens_size: i64) -> Vec<[f64; 4]> {
    let (w, h) = (stack.width as i64, stack.height as i64);
    let k = coc.k_px as f64;
    let rel = |d: f32| d as f64 - coc.focus_disparity as f64;
    let n = (w * h) as usize;
    let mut out = vec![[0.0f64; 4]; n];
    let mut transmittance = vec![1.0f64; n];
    for layer in &stack.layers {
        let mut num = vec![[0.0f64; 3]; n];
        let mut den = vec![0.0f64; n];
        for yi in 0..n {
            let alpha_y = layer.rgba.pixels[yi][3] as f64;
            if alpha_y <= 0.0 {
                continue;
            }
            let straight: Vec<f64> = (0..3).map(|c| layer.rgba.pixels[yi][c] as f64 / alpha_y).collect();
            let d_y = rel(layer.disparity[yi]);
            let (py, px) = (yi as i64 / w, yi as i64 % w);
            for qy in (py - lens_size).max(0)..=(py + lens_size).min(h - 1) {
                for qx in (px - lens_size).max(0)..=(px + lens_size).min(w - 1) {
                    let xi = (qy * w + qx) as usize;
                    let d_x = rel(layer.disparity[xi]);
                    let a = d_y.abs() * k + 1.0;
                    let b = (((qx - px) * (qx - px) + (qy - py) * (qy - py)) as f64).sqrt();
                    let scatter = 0.1 / (0.1 + (-(a - b) * 3.0).exp() + 1e-6);
                    let occlusion = if xi == yi {
                        1.0
                    } else {
                        let in_focal = 1.0 - (-3.0 * (d_x.abs() * k).powi(2)).exp();
                        let r = 0.5 + 0.5 * (10.0 * (d_y - d_x - 0.1)).tanh();
                        (1.0 - in_focal) * r + in_focal
                    };
                    let weight = scatter * occlusion * alpha_y / (a * a);
                    for c in 0..3 {
                        num[xi][c] += straight[c] * weight;
                    }
                    den[xi] += weight;
                }
            }
        }
        for xi in 0..n {
            let (qy, qx) = (xi as i64 / w, xi as i64 % w);
            let r_x = rel(layer.disparity[xi]).abs() * k;
            let half = (((r_x + 1.0) / 2.0) as i64).min(lens_size);
            let (mut sum, mut count) = (0.0, 0.0);
            for py in (qy - half).max(0)..=(qy + half).min(h - 1) {
                for px in (qx - half).max(0)..=(qx + half).min(w - 1) {
                    sum += layer.rgba.pixels[(py * w + px) as usize][3] as f64;
                    count += 1.0;
                }
            }
            let v = sum / count;
            let colour: [f64; 3] = std::array::from_fn(|c| if den[xi] > 0.0 { num[xi][c] / den[xi] } else { 0.0 });
            for c in 0..3 {
                out[xi][c] += transmittance[xi] * v * colour[c];
            }
            out[xi][3] += transmittance[xi] * v;
            transmittance[xi] *= 1.0 - v;
        }
    }
    out
}
