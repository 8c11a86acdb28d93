//! The depth of spilled light (issue 46): a small bright source's pixel-filter spill takes the
//! source's depth below a cut's CoC jump, and nothing else moves.
use lensblur::camera::CocModel;
use lensblur::image::Image;
use lensblur::stack::spill_depth::assign_spill_depth;

const SKY: [f32; 4] = [0.02, 0.03, 0.05, 1.0];
/// Street light 8x brighter than display white, one pixel, at disparity `LIGHT`.
const SOURCE: f32 = 8.0;
const LIGHT: f32 = 0.05;
const SIZE: usize = 16;
const CUT_PX: f32 = 0.75;

fn grey(v: f32) -> [f32; 4] {
    [v, v, v, 1.0]
}

/// A dark sky (disparity 0) with a one-pixel source at (8, 8) whose filter spilled 20% of it
/// into the four edge neighbours and 5% into the corners; the depth samples of the spill hit
/// the sky, as a renderer writes them.
fn light_over_sky() -> (Image, Vec<f32>) {
    let spill = |x: usize, y: usize| -> f32 {
        match (x.abs_diff(8), y.abs_diff(8)) {
            (0, 0) => 1.0,
            (1, 0) | (0, 1) => 0.2,
            (1, 1) => 0.05,
            _ => 0.0,
        }
    };
    let image = Image::from_fn(SIZE, SIZE, |x, y| {
        let s = spill(x, y);
        [0, 1, 2, 3].map(|k| if k == 3 { 1.0 } else { SKY[k] + s * SOURCE })
    });
    let disparity = (0..SIZE * SIZE).map(|i| if (i % SIZE, i / SIZE) == (8, 8) { LIGHT } else { 0.0 }).collect();
    (image, disparity)
}

/// Focus at disparity 1, so the sky's CoC is `k` and the light's `k (1 - LIGHT)`.
fn lens(k: f32) -> CocModel {
    CocModel::new(k, 1.0).unwrap()
}

#[test]
fn spill_below_a_cut_takes_the_source_depth_and_the_sky_keeps_its_own() {
    let (image, disparity) = light_over_sky();
    // Sky CoC 6 px, light 5.7 px: a 0.3 px jump, no cut; without the pass the spill would be
    // blurred 0.3 px wider than the light itself.
    let out = assign_spill_depth(&image, &disparity, &lens(6.0), CUT_PX);
    for y in 0..SIZE {
        for x in 0..SIZE {
            let near = x.abs_diff(8) <= 1 && y.abs_diff(8) <= 1;
            let want = if near { LIGHT } else { 0.0 };
            assert_eq!(out[y * SIZE + x], want, "pixel ({x}, {y})");
        }
    }
}

#[test]
fn spill_across_a_cut_is_left_to_the_matting() {
    let (image, disparity) = light_over_sky();
    // Sky CoC 30 px, light 28.5 px: a 1.5 px jump is a cut, where the matting splits the
    // mixed pixels; this pass must not move them.
    let out = assign_spill_depth(&image, &disparity, &lens(30.0), CUT_PX);
    assert_eq!(out, disparity);
}

#[test]
fn a_pixel_mostly_its_own_surface_keeps_its_depth() {
    // A textured far wall (luminance 1.0 and 0.6 in a checker) beside a slightly brighter
    // near pixel: the wall pixels are within twice their own median, so they hold their own
    // surface's light and keep the wall's depth.
    let wall = |x: usize, y: usize| if (x + y) % 2 == 0 { 1.0 } else { 0.6 };
    let image = Image::from_fn(SIZE, SIZE, |x, y| if (x, y) == (8, 8) { grey(1.5) } else { grey(wall(x, y)) });
    let disparity: Vec<f32> = (0..SIZE * SIZE).map(|i| if i == 8 * SIZE + 8 { 0.3 } else { 0.2 }).collect();
    let out = assign_spill_depth(&image, &disparity, &lens(2.0), CUT_PX);
    assert_eq!(out, disparity);
}

#[test]
fn a_frame_without_depth_structure_is_unchanged() {
    let image = Image::from_fn(SIZE, SIZE, |x, y| grey(((x * 7 + y * 3) % 11) as f32));
    let disparity = vec![0.4; SIZE * SIZE];
    assert_eq!(assign_spill_depth(&image, &disparity, &lens(10.0), CUT_PX), disparity);
}
