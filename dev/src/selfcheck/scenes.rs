//! The small scenes of the self-check (and of the GPU tests that probe one path further). Sizes
//! never divide the 16x16 search tiles; layers mix soft alpha, holes and HDR highlights; depth
//! slopes keep every CoC radius off the compat model's box-size steps int((r + 1) / 2), where
//! f32 and f64 would legitimately round to different integer boxes.
use lensblur::image::Image;
use lensblur::render::MethodSettings;
use lensblur::stack::{Layer, LayerStack};

/// Three layers: a blurred near square with soft alpha, an in-focus textured ring, a far HDR
/// background with highlights (up to 40). With K = 25 and focus 0.5: CoC up to ~12 px in
/// front, ~10 px behind.
pub fn forward(w: usize, h: usize) -> LayerStack {
    let near = Layer {
        name: "near".into(),
        rgba: Image::from_fn(w, h, |x, y| {
            let a = if (8..24).contains(&x) && (6..22).contains(&y) {
                1.0
            } else if (6..26).contains(&x) && (4..24).contains(&y) {
                0.4
            } else {
                0.0
            };
            [0.9 * a, 0.2 * a, 0.1 * a, a]
        }),
        disparity: (0..w * h).map(|i| 0.9 + 0.0021 * (i % w) as f32).collect(),
    };
    let ring = Layer {
        name: "ring".into(),
        rgba: Image::from_fn(w, h, |x, y| {
            let d = ((x as f32 - 30.0).powi(2) + (y as f32 - 20.0).powi(2)).sqrt();
            let a = if (6.0..12.0).contains(&d) { 1.0 } else { 0.0 };
            let v = 0.5 + 0.4 * ((x + y) as f32 * 0.7).sin();
            [v * a, (1.0 - v) * a, 0.3 * a, a]
        }),
        disparity: vec![0.5; w * h],
    };
    let far = Layer {
        name: "far".into(),
        rgba: Image::from_fn(w, h, |x, y| {
            let highlight = if (x * 7 + y * 13) % 53 == 0 { 40.0 } else { 0.0 };
            let v = ((x * 3 + y * 5) % 17) as f32 / 17.0;
            [v + highlight, 0.5 * v, 1.0 - v, 1.0]
        }),
        disparity: (0..w * h).map(|i| 0.1 + 0.001 * (i / w) as f32).collect(),
    };
    LayerStack::new(w, h, vec![near, ring, far]).expect("a valid stack")
}

/// A deterministic value in [-1, 1) per index.
pub fn hash(i: usize) -> f32 {
    let x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5851_F42D_4C95_7F2D;
    let x = (x ^ (x >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    ((x >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
}

/// Three layers for the backward pass: a near blob with a soft alpha rim (disparity `near_d`
/// plus a small slope), a near-focus textured layer with holes, an opaque far layer. With
/// K = 12 and focus 0.5: CoC up to `12 * max |d - 0.5|` px.
pub fn backward(w: usize, h: usize, near_d: f32) -> LayerStack {
    let (cx, cy) = (w as f32 * 0.4, h as f32 * 0.45);
    let near = Layer {
        name: "near".into(),
        rgba: Image::from_fn(w, h, |x, y| {
            let d = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt() / (h as f32 * 0.25);
            let a = if d < 0.8 {
                1.0
            } else if d < 1.1 {
                0.5
            } else {
                0.0
            };
            [0.9 * a, (0.2 + 0.01 * x as f32) * a, 0.4 * a, a]
        }),
        disparity: (0..w * h)
            .map(|i| near_d + 0.0013 * (i % w) as f32 / w as f32 * 16.0 - 0.0007 * (i / w) as f32 / h as f32 * 16.0)
            .collect(),
    };
    let mid = Layer {
        name: "mid".into(),
        rgba: Image::from_fn(w, h, |x, y| {
            let a = if (x + 2 * y) % 7 == 0 {
                0.0
            } else if x > w / 2 {
                0.75
            } else {
                1.0
            };
            [(0.3 + 0.1 * (y % 3) as f32) * a, 0.7 * a, 2.0 * a, a]
        }),
        disparity: (0..w * h)
            .map(|i| 0.5137 + 0.1 * (i % w) as f32 / w as f32 + 0.011 * (i / w) as f32 / h as f32)
            .collect(),
    };
    let far = Layer {
        name: "far".into(),
        rgba: Image::from_fn(w, h, |x, y| {
            let highlight = if (x * 7 + y * 13) % 53 == 0 { 8.0 } else { 0.0 };
            let v = ((x * 5 + y * 3) % 7) as f32 / 7.0;
            [v + highlight, 0.5 - 0.3 * v, 3.0 * v + 0.1, 1.0]
        }),
        disparity: (0..w * h)
            .map(|i| 0.2113 + 0.03 * (i % w) as f32 / w as f32 + 0.021 * (i / w) as f32 / h as f32)
            .collect(),
    };
    LayerStack::new(w, h, vec![near, mid, far]).expect("a valid stack")
}

/// dL/d(output) of the backward checks: deterministic noise of both signs.
pub fn grad_output(w: usize, h: usize) -> Image {
    Image::from_fn(w, h, |x, y| std::array::from_fn(|c| hash((y * w + x) * 4 + c)))
}

/// Few lens samples keep the CPU references of the lens-sampling renderers quick; a tilted
/// focal plane makes Virtual DSLR's relative disparity depend on the position in the frame.
pub fn few_samples() -> MethodSettings {
    let focus = lensblur::render::vdslr::FocusField::Tilt { gradient: [0.004, -0.006] };
    MethodSettings { samples: 24, focus, ..MethodSettings::default() }
}
