//! Auto-layering of a flat RGB+Z image: layers in CoC, soft cuts, hidden background fill.
use lensblur::camera::CocModel;
use lensblur::image::Image;
use lensblur::stack::{split_into_layers, AutoLayerOptions, LayerStack};

const BG: [f32; 4] = [0.1, 0.6, 0.3, 1.0];
const FG: [f32; 4] = [0.9, 0.2, 0.1, 1.0];
const MID: [f32; 4] = [0.2, 0.2, 0.8, 1.0];

fn mix(f: [f32; 4], b: [f32; 4], a: f32) -> [f32; 4] {
    [0, 1, 2, 3].map(|k| a * f[k] + (1.0 - a) * b[k])
}

/// A 32x32 background at disparity 0.25 with a foreground square at disparity 1 whose left
/// edge column covers 30% of its pixels and right edge column 70% (anti-aliased colour,
/// depth from the pixel centre, as renderers write it).
fn square_scene() -> (Image, Vec<f32>) {
    let coverage = |x: usize, y: usize| -> f32 {
        if !(8..20).contains(&y) {
            return 0.0;
        }
        match x {
            10 => 0.3,
            11..=20 => 1.0,
            21 => 0.7,
            _ => 0.0,
        }
    };
    let image = Image::from_fn(32, 32, |x, y| mix(FG, BG, coverage(x, y)));
    let disparity = (0..32 * 32).map(|i| if coverage(i % 32, i / 32) >= 0.5 { 1.0 } else { 0.25 }).collect();
    (image, disparity)
}

fn composite(stack: &LayerStack) -> Image {
    let mut out = Image::new(stack.width, stack.height);
    for layer in &stack.layers {
        for (o, p) in out.pixels.iter_mut().zip(&layer.rgba.pixels) {
            let t = 1.0 - o[3];
            *o = [0, 1, 2, 3].map(|k| o[k] + t * p[k]);
        }
    }
    out
}

fn max_diff(a: &Image, b: &Image) -> f32 {
    a.pixels.iter().zip(&b.pixels).flat_map(|(p, q)| (0..4).map(move |k| (p[k] - q[k]).abs())).fold(0.0, f32::max)
}

/// Both mattings, each with the tolerance a test holds it to: the solved matte (the default)
/// trades exactness on these two-colour toy edges for robustness on real ones, where its depth
/// prior pulls alpha a few hundredths towards the Z sample.
fn both(solved: f32, sampled_tolerance: f32) -> [(AutoLayerOptions, f32); 2] {
    [(AutoLayerOptions::default(), solved), (AutoLayerOptions::sampled(), sampled_tolerance)]
}

fn coc() -> CocModel {
    // K = 20 px per unit disparity, focus on the background: the square has a 15 px CoC.
    CocModel::new(20.0, 0.25).unwrap()
}

#[test]
fn two_depths_split_into_two_layers_whose_over_composite_is_the_input() {
    let (image, disparity) = square_scene();
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 2);
    // Exact by construction (front = c - (1-a) B, back = B); 1e-5 covers f32 rounding.
    let err = max_diff(&composite(&stack), &image);
    assert!(err < 1e-5, "composite differs from the input by {err}");
    assert!(stack.layers[0].disparity.iter().all(|&d| (d - 1.0).abs() < 1e-6), "front layer keeps the square's depth");
    assert!(
        stack.layers[1].disparity.iter().all(|&d| (d - 0.25).abs() < 1e-6),
        "back layer keeps the background depth"
    );
}

#[test]
fn filled_background_under_the_square_has_no_foreground_colour() {
    let (image, disparity) = square_scene();
    // Sampled: the fill draws only on pure background pixels, 1e-4 is float noise. Solved: the
    // background estimate at the 30% column keeps under 2% of the square's colour.
    for (options, tolerance) in both(0.02, 1e-4) {
        let stack = split_into_layers(&image, &disparity, &coc(), &options);
        let back = &stack.layers[1].rgba;
        for y in 8..20 {
            for x in 10..=21 {
                let p = back.get(x, y);
                assert!((0..4).all(|k| (p[k] - BG[k]).abs() < tolerance), "{:?}: ({x},{y}) = {p:?}", options.matting);
            }
        }
    }
}

#[test]
fn silhouette_pixels_get_fractional_alpha_matching_coverage() {
    let (image, disparity) = square_scene();
    // Colours are exact two-colour mixes: the sampled projection recovers coverage up to
    // rounding; the solved matte within 0.06, its prior (the Z sample) pulling it.
    for (options, tolerance) in both(0.06, 1e-4) {
        let stack = split_into_layers(&image, &disparity, &coc(), &options);
        let front = &stack.layers[0].rgba;
        assert!((front.get(10, 12)[3] - 0.3).abs() < tolerance, "{:?}: {:?}", options.matting, front.get(10, 12));
        assert!((front.get(21, 12)[3] - 0.7).abs() < tolerance, "{:?}: {:?}", options.matting, front.get(21, 12));
        assert!((front.get(15, 12)[3] - 1.0).abs() < 1e-6);
        assert_eq!(front.get(3, 3)[3], 0.0, "far from the square the front layer is empty");
    }
}

#[test]
fn every_farther_layer_is_filled_under_every_nearer_one() {
    // Background everywhere, a middle bar at disparity 0.6, a front square at disparity 1.
    let disp = |x: usize, y: usize| -> f32 {
        if (12..20).contains(&x) && (12..20).contains(&y) {
            1.0
        } else if (4..28).contains(&x) && (14..18).contains(&y) {
            0.6
        } else {
            0.25
        }
    };
    let colour = |d: f32| {
        if d == 1.0 {
            FG
        } else if d == 0.6 {
            MID
        } else {
            BG
        }
    };
    let image = Image::from_fn(32, 32, |x, y| colour(disp(x, y)));
    let disparity: Vec<f32> = (0..32 * 32).map(|i| disp(i % 32, i / 32)).collect();
    for (options, tolerance) in both(1e-3, 1e-4) {
        let stack = split_into_layers(&image, &disparity, &coc(), &options);
        assert_eq!(stack.layers.len(), 3);
        assert!(stack.layers[2].rgba.pixels.iter().all(|p| p[3] == 1.0), "the back layer is opaque everywhere");
        // The middle layer continues under the square along the bar (rows 14..18 at x = 15) with
        // the bar's own colour (solved: within 1e-3, the background estimates seeding the fill);
        // its coverage there is extended from around the square (bar left and right over 4
        // rows, background on the rest of its outline), so partial.
        let under = stack.layers[1].rgba.get(15, 15);
        assert!(under[3] > 0.1 && under[3] <= 1.0, "{under:?}");
        assert!((0..3).all(|k| (under[k] / under[3] - MID[k]).abs() < tolerance), "{:?}: {under:?}", options.matting);
        // Where the bar is not on both sides of the square (rows 12, 19), the layer fades out.
        assert!(stack.layers[1].rgba.get(15, 12)[3] < under[3], "{:?}", options.matting);
        assert!(max_diff(&composite(&stack), &image) < 1e-5);
    }
}

#[test]
fn a_continuous_ramp_is_sliced_without_soft_bands() {
    // Disparity rising smoothly left to right: several slices, but no discontinuity, so
    // every alpha stays 0 or 1 and the composite is exact.
    let image = Image::from_fn(64, 8, |x, _| [x as f32 / 64.0, 0.5, 0.2, 1.0]);
    let disparity: Vec<f32> = (0..64 * 8).map(|i| 0.25 + (i % 64) as f32 / 64.0).collect();
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    assert!(stack.layers.len() >= 4, "20 px of CoC at 4 px spacing gives several layers, got {}", stack.layers.len());
    // Visible pixels (not under an opaque nearer layer) are all or nothing; what is hidden
    // carries the extended coverage and never shows.
    let mut covered = vec![0.0f32; 64 * 8];
    for layer in &stack.layers {
        for (c, p) in covered.iter_mut().zip(&layer.rgba.pixels) {
            assert!(*c >= 1.0 || p[3] == 0.0 || p[3] == 1.0, "{p:?}");
            *c += (1.0 - *c) * p[3];
        }
    }
    assert!(max_diff(&composite(&stack), &image) < 1e-6);
}

#[test]
fn a_spacing_far_below_a_pixel_still_gives_at_most_max_layers_and_an_exact_composite() {
    // `--layer-spacing 1e-6` (clamped to 1e-3 px): before the cap, this ramp over 8000 px of CoC
    // asked for 8 million slices; now one per histogram bin at most, truncated to `max_layers`.
    let (w, h) = (256, 4);
    let image = Image::from_fn(w, h, |x, _| [x as f32 / w as f32, 0.5, 0.2, 1.0]);
    let disparity: Vec<f32> = (0..w * h).map(|i| (i % w) as f32 / w as f32 * 400.0).collect();
    let options = AutoLayerOptions { coc_spacing_px: 1e-6, ..AutoLayerOptions::default() };
    let stack = split_into_layers(&image, &disparity, &coc(), &options);
    assert_eq!(stack.layers.len(), options.max_layers, "a long ramp fills every layer allowed");
    assert!(max_diff(&composite(&stack), &image) < 1e-6);
}

#[test]
fn planes_whose_cocs_differ_by_more_than_a_pixel_get_layers_of_their_own() {
    // Issue 22's five planes at 256^2 (signed CoC +6.9, 0, -4.4, -6.9, -9.9 px: the last two
    // 3 px apart), as vertical strips, and two planes only 0.5 px apart that may share one.
    let k = 20.0;
    let cocs = [6.9f32, 0.0, -4.4, -6.9, -9.9, -10.4];
    let disparity: Vec<f32> = (0..60 * 4).map(|i| 0.25 + cocs[(i % 60) / 10] / k).collect();
    let image = Image::from_fn(60, 4, |x, _| [0.1 * (x / 10) as f32, 0.5, 0.2, 1.0]);
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 5, "one layer per plane, the last two planes merged");
    for (l, layer) in stack.layers.iter().enumerate() {
        let own: Vec<usize> = (0..60).filter(|&x| layer.rgba.get(x, 1)[3] == 1.0 && layer.disparity[60 + x] == disparity[60 + x]).collect();
        assert!(!own.is_empty(), "layer {l} holds a plane");
    }
    assert!(max_diff(&composite(&stack), &image) < 1e-5);
}

#[test]
fn a_layer_is_not_extended_under_a_thin_wire_where_it_is_absent() {
    // Sky at disparity 0.25, an in-focus subject disc at 0.5 and a 1 px wire at disparity 1
    // crosses both. Under the wire, the subject layer continues inside the disc only.
    let inside = |x: usize, y: usize| (x as f32 - 16.0).powi(2) + (y as f32 - 16.0).powi(2) < 64.0;
    let disp = |x: usize, y: usize| if y == 16 { 1.0 } else if inside(x, y) { 0.5 } else { 0.25 };
    let image = Image::from_fn(32, 32, |x, y| if y == 16 { FG } else if inside(x, y) { MID } else { BG });
    let disparity: Vec<f32> = (0..32 * 32).map(|i| disp(i % 32, i / 32)).collect();
    let stack = split_into_layers(&image, &disparity, &CocModel::new(20.0, 0.5).unwrap(), &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 3);
    let subject = &stack.layers[1].rgba;
    assert!(subject.get(16, 16)[3] > 0.9, "under the wire inside the disc: {:?}", subject.get(16, 16));
    assert!(subject.get(2, 16)[3] < 0.1, "under the wire in the sky: {:?}", subject.get(2, 16));
}

#[test]
fn a_sharp_hair_strand_keeps_its_darkness_out_of_the_background() {
    // In focus (disparity 1, CoC 0): a skin block and a dark 1 px strand leaving it to the
    // right along row 16; one pixel above the strand is half strand, half sky (depth: sky).
    // The means would pair the sky with the skin beside the strand; sampling finds the strand.
    const HAIR: [f32; 4] = [0.05, 0.03, 0.02, 1.0];
    let skin = |x: usize, y: usize| (4..12).contains(&x) && (10..23).contains(&y);
    let strand = |x: usize, y: usize| y == 16 && (12..28).contains(&x);
    let image = Image::from_fn(32, 32, |x, y| {
        if skin(x, y) {
            FG
        } else if strand(x, y) {
            HAIR
        } else if (x, y) == (20, 15) {
            mix(HAIR, BG, 0.5)
        } else {
            BG
        }
    });
    let disparity: Vec<f32> = (0..32 * 32).map(|i| if skin(i % 32, i / 32) || strand(i % 32, i / 32) { 1.0 } else { 0.25 }).collect();
    let stack = split_into_layers(&image, &disparity, &CocModel::new(20.0, 1.0).unwrap(), &AutoLayerOptions::sampled());
    assert_eq!(stack.layers.len(), 2);
    let back = stack.layers[1].rgba.get(20, 15);
    assert!((0..3).all(|k| (back[k] - BG[k]).abs() < 0.05), "background under the mixed pixel: {back:?}");
    let front = stack.layers[0].rgba.get(20, 15);
    assert!((front[3] - 0.5).abs() < 0.1, "the strand covers half the pixel: {front:?}");
    assert!(max_diff(&composite(&stack), &image) < 1e-5);
}

/// In-focus dark hair (disparity 1, CoC 0): 1 px strands at the even columns 10..=20 over an
/// HDR light (30) on a dark far background (disparity 0.25). The odd columns between strands
/// are 30% strand, 70% light; their depth sample (a jittered Z pass, as Cycles writes it) hit
/// a strand on even rows and the light on odd rows. No pixel of the strands' layer is unmixed.
fn light_behind_hair() -> (Image, Vec<f32>) {
    const DARK: [f32; 4] = [0.05, 0.04, 0.03, 1.0];
    const SKY: [f32; 4] = [0.02, 0.02, 0.04, 1.0];
    const LIGHT: [f32; 4] = [30.0, 24.0, 15.0, 1.0];
    let hair = |x: usize, y: usize| (10..=20).contains(&x) && (8..22).contains(&y);
    let image = Image::from_fn(32, 32, |x, y| match () {
        _ if hair(x, y) && x % 2 == 0 => DARK,
        _ if hair(x, y) => mix(DARK, LIGHT, 0.3),
        _ if (8..=23).contains(&x) && (6..24).contains(&y) => LIGHT,
        _ => SKY,
    });
    let disparity = (0..32 * 32)
        .map(|i| {
            let (x, y) = (i % 32, i / 32);
            if hair(x, y) && (x % 2 == 0 || y % 2 == 0) {
                1.0
            } else {
                0.25
            }
        })
        .collect();
    (image, disparity)
}

#[test]
fn hdr_light_between_in_focus_hair_strands_stays_out_of_the_front_layer() {
    let (image, disparity) = light_behind_hair();
    let stack = split_into_layers(&image, &disparity, &CocModel::new(20.0, 1.0).unwrap(), &AutoLayerOptions::sampled());
    assert_eq!(stack.layers.len(), 2);
    let front = &stack.layers[0].rgba;
    for (i, p) in front.pixels.iter().enumerate() {
        // The strands' colour is at most 0.05: a front pixel brighter than its alpha times
        // that (plus margin) holds light that would ring the in-focus hair.
        assert!((0..3).all(|k| p[k] <= p[3] * 0.1 + 1e-4), "front ({}, {}) = {p:?}", i % 32, i / 32);
    }
    let mixed = front.get(13, 14);
    assert!(mixed[3] < 0.9, "the light shows through between strands: {mixed:?}");
    let back = stack.layers[1].rgba.get(13, 14);
    assert!(back[0] > 10.0, "the light is in the back layer: {back:?}");
    for layer in &stack.layers {
        assert!(layer.rgba.pixels.iter().all(|p| (0.0..=1.0).contains(&p[3])), "alpha stays in [0, 1]");
    }
    // Front + (1 - alpha) back is the input (f32 rounding of values up to 30: 1e-4 relative).
    let err = max_diff(&composite(&stack), &image);
    assert!(err < 3e-3, "composite differs from the input by {err}");
}

#[test]
fn a_mostly_front_pixel_labelled_back_leaves_no_front_colour_in_the_back() {
    // A textured in-focus front (bright and dark red columns) over a green background; the
    // right edge column is 80% front, but its depth sample hit the background.
    const BRIGHT: [f32; 4] = [0.95, 0.3, 0.25, 1.0];
    let front_colour = |x: usize| if x % 2 == 0 { BRIGHT } else { [0.45, 0.1, 0.05, 1.0] };
    let image = Image::from_fn(32, 32, |x, y| match x {
        10..=20 if (8..24).contains(&y) => front_colour(x),
        21 if (8..24).contains(&y) => mix(BRIGHT, BG, 0.8),
        _ => BG,
    });
    let disparity: Vec<f32> = (0..32 * 32).map(|i| if (10..=20).contains(&(i % 32)) && (8..24).contains(&(i / 32)) { 1.0 } else { 0.25 }).collect();
    let stack = split_into_layers(&image, &disparity, &CocModel::new(20.0, 1.0).unwrap(), &AutoLayerOptions::default());
    let back = &stack.layers[1].rgba;
    for y in 0..32 {
        for x in 0..32 {
            let p = back.get(x, y);
            // Background colour only (its own pixels are all BG): 0.1 leaves room for the
            // clamp's slack, front red would be 0.6+ off in red.
            assert!((0..3).all(|k| (p[k] - BG[k] * p[3]).abs() < 0.1), "back ({x}, {y}) = {p:?}");
            assert!((0.0..=1.0).contains(&p[3]));
        }
    }
    let err = max_diff(&composite(&stack), &image);
    assert!(err < 1e-4, "over differs from the input by {err}");
}

#[test]
fn a_light_cut_by_an_in_focus_edge_continues_under_it_only_a_few_pixels() {
    // A 6 px wide HDR light on a dark far background (disparity 0.25), its right part hidden
    // by an in-focus dark square (disparity 1, CoC 0) from column 16 on.
    const DARK: [f32; 4] = [0.05, 0.04, 0.03, 1.0];
    const SKY: [f32; 4] = [0.02, 0.02, 0.04, 1.0];
    const LIGHT: [f32; 4] = [20.0, 16.0, 10.0, 1.0];
    let front = |x: usize, y: usize| x >= 16 && (4..28).contains(&y);
    let image = Image::from_fn(32, 32, |x, y| match () {
        _ if front(x, y) => DARK,
        _ if (10..16).contains(&x) && (12..20).contains(&y) => LIGHT,
        _ => SKY,
    });
    let disparity: Vec<f32> = (0..32 * 32).map(|i| if front(i % 32, i / 32) { 1.0 } else { 0.25 }).collect();
    let stack = split_into_layers(&image, &disparity, &CocModel::new(20.0, 1.0).unwrap(), &AutoLayerOptions::default());
    let back = &stack.layers[1].rgba;
    // Mirrored across the edge at full strength just under the square, as the disc goes on...
    assert!(back.get(17, 15)[0] > 10.0, "under the edge: {:?}", back.get(17, 15));
    // ...but not far under it, where the smooth fill (range-compressed: no HDR smear) rules.
    assert!(back.get(26, 15)[0] < 1.0, "far under the square: {:?}", back.get(26, 15));
    assert!(back.pixels.iter().all(|p| (0.0..=1.0).contains(&p[3])));
}

/// Issue 35's ghost fence: a blurred wire (disparity 1, CoC 15 px, focus on the wall at 0.25)
/// lit by the sky to 1.4 (HDR) crosses an in-focus wall of 0.45 along row 16 as two rows of
/// mixed pixels, 70% and 30% wire, their one-sample depth on the wire in even columns and on
/// the wall in odd ones. No pixel of the wire is unmixed. The wall layer must show the wall
/// under every wire pixel (a wire's share left in it stays sharp: a ghost of the fence), and
/// the wire's light must go to the wire's layer, by its coverage from the colours.
#[test]
fn an_hdr_lit_blurred_wire_leaves_no_ghost_in_the_in_focus_back() {
    const WIRE: [f32; 4] = [1.4, 1.4, 1.3, 1.0];
    const WALL: [f32; 4] = [0.45, 0.4, 0.35, 1.0];
    let cover = |y: usize| match y {
        16 => 0.7,
        17 => 0.3,
        _ => 0.0,
    };
    let image = Image::from_fn(32, 32, |_, y| mix(WIRE, WALL, cover(y)));
    let on_wire = |x: usize, y: usize| cover(y) > 0.0 && x % 2 == 0;
    let disparity: Vec<f32> = (0..32 * 32).map(|i| if on_wire(i % 32, i / 32) { 1.0 } else { 0.25 }).collect();
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::sampled());
    assert_eq!(stack.layers.len(), 2);
    let (front, back) = (&stack.layers[0].rgba, &stack.layers[1].rgba);
    for x in 4..28 {
        for y in [16, 17] {
            let b = back.get(x, y);
            // 0.02: the wall is flat, so its local colour is exact; the wire's share would add 0.28 to 0.67.
            assert!((0..3).all(|k| (b[k] - WALL[k]).abs() < 0.02), "wall under the wire at ({x}, {y}): {b:?}");
            // Coverage from the colours (linear mixing), whichever side the depth sample hit,
            // relative to the wire's most covered pixel (its own colour is that pixel's: a
            // wire that never fills a pixel cannot show more): 1 on row 16, 3/7 on row 17.
            let (a, expected) = (front.get(x, y)[3], cover(y) / 0.7);
            assert!((a - expected).abs() < 0.05, "wire coverage at ({x}, {y}): {a}, expected {expected}");
        }
    }
    assert!(max_diff(&composite(&stack), &image) < 1e-4, "over gives the input");
}

/// An in-focus wire (column 16, disparity 1, CoC 0) over a dark wall (disparity 0.25, CoC 15
/// px), with `behind` behind the wire around (15, 16): the wire pixel beside it shows the
/// light through the wire (half covered, depth sample on the wire), as a wire crossing in
/// front of a street light does in a render.
fn wire_over(behind: impl Fn(usize, usize) -> [f32; 4]) -> (Image, Vec<f32>) {
    const WIRE: [f32; 4] = [0.08, 0.06, 0.05, 1.0];
    let image = Image::from_fn(32, 32, |x, y| if x == 16 { mix(WIRE, behind(x, y), 0.5) } else { behind(x, y) });
    let disparity = (0..32 * 32).map(|i| if i % 32 == 16 { 1.0 } else { 0.25 }).collect();
    (image, disparity)
}

#[test]
fn a_compact_light_behind_an_in_focus_wire_is_not_pulled_into_the_sharp_layer() {
    // A street light (80, two pixels wide) whose light the wire pixel beside it shares.
    let light = |x: usize, y: usize| if (15..=16).contains(&x) && (15..=16).contains(&y) { grey(80.0) } else { grey(0.05) };
    let (image, disparity) = wire_over(light);
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 2);
    // The light's own pixel belongs to the wall: the sharp layer may hold at most a tenth of
    // it, else the light renders as a sharp dot instead of a disc.
    let front = stack.layers[0].rgba.get(15, 16);
    assert!(front[3] < 0.1 && front[0] < 8.0, "the light's pixel in the sharp layer: {front:?}");
    // The light-lit wire pixel gives the back layer the light it shows.
    let back = stack.layers[1].rgba.get(16, 16);
    assert!(back[0] > 20.0, "the light behind the wire is in the back layer: {back:?}");
    let err = max_diff(&composite(&stack), &image);
    assert!(err < 3e-3, "composite differs from the input by {err}");
}

#[test]
fn a_lamp_behind_a_wire_that_barely_covers_it_still_goes_to_the_back() {
    // An in-focus wire two pixels wide (x = 15, 16) crosses a lamp (x = 16, 17): it covers all of
    // column 15 but 5% of column 16, whose pixels hold 95% of the lamp's 80 and are brighter
    // than the lamp's own pixels beside them (75, its fall-off): the dev-60 scene of issue 46.
    const WIRE: [f32; 4] = [0.08, 0.06, 0.05, 1.0];
    let lamp = |y: usize| (15..=16).contains(&y);
    let image = Image::from_fn(32, 32, |x, y| match x {
        15 => WIRE,
        16 if lamp(y) => mix(WIRE, grey(80.0), 0.05),
        16 => mix(WIRE, grey(0.05), 0.05),
        17 if lamp(y) => grey(75.0),
        _ => grey(0.05),
    });
    let disparity = (0..32 * 32).map(|i| if (15..=16).contains(&(i % 32)) { 1.0 } else { 0.25 }).collect::<Vec<f32>>();
    // Focus on the wire: the lamp behind it is blurred 15 px.
    let focus_on_wire = CocModel::new(20.0, 1.0).unwrap();
    let stack = split_into_layers(&image, &disparity, &focus_on_wire, &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 2);
    let front = stack.layers[0].rgba.get(16, 16);
    assert!(front[0] < 8.0, "the sharp layer keeps at most a tenth of the lamp: {front:?}");
    let back = stack.layers[1].rgba.get(16, 16);
    assert!(back[0] > 20.0, "the lamp's light over the wire is in the back layer: {back:?}");
    let err = max_diff(&composite(&stack), &image);
    assert!(err < 3e-3, "composite differs from the input by {err}");
}

#[test]
fn a_sunlit_wire_in_focus_keeps_its_own_light_beside_its_spill() {
    // An in-focus wire (row 16) lit to 5.0 over a dark, blurred background; the pixel filter
    // spills 92% of its light into the background row above it (row 15, background depth), as
    // bright beside it as a lamp would be (the dev-90 scene of issue 46). The light is the
    // wire's own: every front pixel holds it, so it stays in the sharp layer.
    let image = Image::from_fn(32, 32, |_, y| match y {
        16 => grey(5.0),
        15 => grey(4.6),
        _ => grey(0.05),
    });
    let disparity = (0..32 * 32).map(|i| if i / 32 == 16 { 1.0 } else { 0.25 }).collect::<Vec<f32>>();
    let focus_on_wire = CocModel::new(20.0, 1.0).unwrap();
    let stack = split_into_layers(&image, &disparity, &focus_on_wire, &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 2);
    for x in 4..28 {
        let front = stack.layers[0].rgba.get(x, 16);
        assert!(front[0] > 4.0, "wire pixel ({x}, 16) keeps its light in the sharp layer: {front:?}");
    }
}

/// Pixels of the dev-24 scene of issue 46 (a Cycles render, brightest channel, x 246..254 and y
/// 177..185 of 256^2): a street lamp behind an in-focus wire under two pixels wide (columns 3
/// and 4, whose one-sample depth hit the wire); the lamp shows on both sides of the wire and
/// through it, brightest (32.7) on a pixel whose depth hit the wall.
const LAMP_BEHIND_WIRE: [[f32; 8]; 8] = [
    [0.08, 0.11, 0.08, 0.06, 0.06, 0.09, 0.01, 0.04],
    [0.02, 0.07, 0.04, 0.07, 0.04, 0.02, 0.04, 0.01],
    [0.02, 0.02, 0.06, 0.04, 3.51, 1.73, 0.01, 0.07],
    [0.07, 0.01, 18.97, 8.70, 25.86, 24.12, 0.01, 0.06],
    [0.03, 0.01, 25.83, 13.83, 31.00, 32.72, 0.08, 0.02],
    [0.04, 0.01, 3.50, 0.06, 10.36, 6.93, 0.01, 0.02],
    [0.03, 0.10, 0.02, 0.06, 0.02, 0.01, 0.00, 0.05],
    [0.09, 0.02, 0.10, 0.07, 0.04, 0.04, 0.02, 0.00],
];

#[test]
fn a_lamp_behind_an_in_focus_wire_leaves_the_wire_layer_even_where_it_lights_the_back_pixels() {
    // The patch in a dark wall (0.05), the wire (x = 15, 16) running the frame's height, focus
    // on the wire. The wall around the lamp is dark, so the matte's background estimate is
    // dark too; the lamp's light it leaves unexplained went all to the sharp layer, which then
    // rendered a sharp lamp instead of a disc (21.74 dB; 22.79 with the light behind the wire
    // held to the wire's colour).
    let patch = |x: usize, y: usize| (12..20).contains(&x) && (12..20).contains(&y);
    let on_wire = |x: usize| (15..=16).contains(&x);
    let image = Image::from_fn(32, 32, |x, y| if patch(x, y) { grey(LAMP_BEHIND_WIRE[y - 12][x - 12]) } else { grey(0.05) });
    let disparity = (0..32 * 32).map(|i| if on_wire(i % 32) { 1.0 } else { 0.25 }).collect::<Vec<f32>>();
    let focus_on_wire = CocModel::new(20.0, 1.0).unwrap();
    let stack = split_into_layers(&image, &disparity, &focus_on_wire, &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 2);
    let (front, back) = (&stack.layers[0].rgba, &stack.layers[1].rgba);
    // The lamp's light the back layer shows past the wire, (1 - alpha) times its colour, of
    // all the lamp's light (its pixels over 1): 0.3% when the sharp layer kept it all, 17%
    // with the light held to the wire's colour, 7% since the wire's thin-line prior is trusted
    // (its pixels above and below the lamp pull the matte towards the wire). Not more: the
    // matte's foreground estimate over the lamp absorbs the light too (it is solved to
    // explain each pixel's colour), and the front keeps what it explains.
    let lamp: Vec<(usize, usize)> = (12..20).flat_map(|y| (12..20).map(move |x| (x, y))).filter(|&(x, y)| image.get(x, y)[0] > 1.0).collect();
    let shown: f32 = lamp.iter().map(|&(x, y)| (1.0 - front.get(x, y)[3]) * back.get(x, y)[0]).sum();
    let total: f32 = lamp.iter().map(|&(x, y)| image.get(x, y)[0]).sum();
    assert!(shown > 0.05 * total, "the back layer shows {shown} of the lamp's {total}");
    let err = max_diff(&composite(&stack), &image);
    assert!(err < 3e-3, "composite differs from the input by {err}");
}

#[test]
fn a_wire_over_a_bright_sky_keeps_its_coverage() {
    // The same wire over an HDR sky (3.0) everywhere: nothing stands out behind it, so the
    // wire pixels keep their depth prior and stay half covered in the sharp layer.
    let (image, disparity) = wire_over(|_, _| grey(3.0));
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    for y in 4..28 {
        let a = stack.layers[0].rgba.get(16, y)[3];
        assert!(a > 0.3, "wire pixel (16, {y}) has alpha {a}");
    }
}

fn grey(v: f32) -> [f32; 4] {
    [v, v, v, 1.0]
}

/// Disparity of signed CoC `s` px under [`coc`] (K = 20, focus at 0.25).
fn at_coc(s: f32) -> f32 {
    0.25 + s / 20.0
}

#[test]
fn blurred_leaves_over_a_sharp_wall_are_cut_although_a_ground_plane_fills_most_of_their_gap() {
    // Top half: a wall in focus with 4x4 leaves at 1.35 px CoC. Bottom half: a ground plane
    // rising from 0 to 0.95 px, which leaves one empty 0.25 px bin below the leaves, a gap
    // narrower than `discontinuity_px` (the dev-39 scene of issue 46).
    let (w, h) = (64, 64);
    let leaf = |x: usize, y: usize| y < 32 && x % 8 < 4 && y % 8 < 4;
    let coc_at = |x: usize, y: usize| if leaf(x, y) { 1.35 } else if y < 32 { 0.0 } else { 0.95 * (y - 32) as f32 / 31.0 };
    let disparity: Vec<f32> = (0..w * h).map(|i| at_coc(coc_at(i % w, i / w))).collect();
    let image = Image::from_fn(w, h, |x, y| if leaf(x, y) { FG } else { BG });
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 2, "the leaves are a layer of their own");
    let front = &stack.layers[0].rgba;
    assert_eq!(front.get(1, 1)[3], 1.0, "a leaf is in the front layer");
    assert_eq!(front.get(5, 5)[3], 0.0, "the wall between leaves is not");
    assert!(max_diff(&composite(&stack), &image) < 1e-5);
    let without = AutoLayerOptions { narrow_gaps: false, ..AutoLayerOptions::default() };
    assert_eq!(split_into_layers(&image, &disparity, &coc(), &without).layers.len(), 1, "the histogram gap alone is no cut");
}

#[test]
fn surfaces_that_meet_gently_along_a_border_stay_one_layer_despite_a_few_jumps() {
    // A ramp from 0 to 0.74 px meets a plateau at 1.01 px along a column (jumps of 0.27 px,
    // across one empty bin); two 4x4 blobs of the plateau's CoC sit on the ramp's low end
    // (32 jumps of at least 0.5 px, fewer than twice the 64 gentle contacts).
    let (w, h) = (64, 64);
    let blob = |x: usize, y: usize| (2..6).contains(&x) && ((10..14).contains(&y) || (40..44).contains(&y));
    let coc_at = |x: usize, y: usize| if x >= 32 || blob(x, y) { 1.01 } else { 0.74 * x as f32 / 31.0 };
    let disparity: Vec<f32> = (0..w * h).map(|i| at_coc(coc_at(i % w, i / w))).collect();
    let image = Image::from_fn(w, h, |x, y| if x >= 32 || blob(x, y) { MID } else { BG });
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 1, "a border of gentle contacts keeps the two surfaces together");
}

#[test]
fn edges_of_a_cut_jumping_less_than_a_cut_gap_are_still_matted() {
    // The square scene with the square 0.65 px of CoC in front of the background: its 30% and
    // 70% edge columns get fractional alpha (within the solved matte's 0.06 of the other tests).
    let (image, disparity) = square_scene();
    let disparity: Vec<f32> = disparity.iter().map(|&d| if d > 0.5 { at_coc(0.65) } else { at_coc(0.0) }).collect();
    let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
    assert_eq!(stack.layers.len(), 2);
    let front = &stack.layers[0].rgba;
    assert!((front.get(10, 12)[3] - 0.3).abs() < 0.06, "{:?}", front.get(10, 12));
    assert!((front.get(21, 12)[3] - 0.7).abs() < 0.06, "{:?}", front.get(21, 12));
    assert!(max_diff(&composite(&stack), &image) < 1e-5);
}

#[test]
fn surfaces_blurred_alike_across_a_narrow_gap_stay_one_layer() {
    // The square scene with both sides far from focus: the square at 13.6 px of CoC over a
    // background at 13.0 (a 0.6 px gap, 4% of their blur), then at 6.0 over 5.4 (10%). Their
    // edges jump by more than `matte_jump_px` all round, so either pair would be a narrow
    // gap's cut; only the second is blurred differently enough for the layers' "over" to be
    // closer to the lens than one layer (dev-842 of issue 46 against dev-36 and dev-68).
    let (image, disparity) = square_scene();
    for (front, back, layers) in [(13.6, 13.0, 1), (6.0, 5.4, 2), (0.65, 0.0, 2)] {
        let disparity: Vec<f32> = disparity.iter().map(|&d| if d > 0.5 { at_coc(front) } else { at_coc(back) }).collect();
        let stack = split_into_layers(&image, &disparity, &coc(), &AutoLayerOptions::default());
        assert_eq!(stack.layers.len(), layers, "square at {front} px over {back} px");
        assert!(max_diff(&composite(&stack), &image) < 1e-5);
    }
}

/// A render job over one flat image through a normalised camera (`guess`: the canvas guessed
/// beyond the frame, the default).
fn flat_job(coc: CocModel, guess: bool) -> lensblur::job::RenderJob {
    use lensblur::input::CameraRequest;
    use lensblur::job::{JobSpec, RenderJob};
    let mut spec = JobSpec {
        method: lensblur::render::Method::Oracle,
        camera: CameraRequest { normalised: Some(coc), ..CameraRequest::default() },
        ..JobSpec::default()
    };
    spec.input.auto_layer.guess_beyond_frame = guess;
    RenderJob::new(spec).unwrap()
}

/// The frame a job keeps of one flat image (`rgba`, depth `z`).
fn job_render(job: &lensblur::job::RenderJob, image: &Image, z: f32) -> Image {
    let rgba: Vec<f32> = image.pixels.iter().flatten().copied().collect();
    let depth = vec![z; image.width * image.height];
    let arrays = lensblur::stack::stack_from_arrays(&rgba, &[image.height, image.width, 4], &depth, &[image.height, image.width], lensblur::stack::DepthKind::Z)
        .unwrap();
    let loaded = job.load_arrays(arrays).unwrap();
    let rendered = job.render(None, &loaded, None).unwrap();
    job.output(&rendered.image, &loaded).unwrap().into_owned()
}

#[test]
fn a_blur_at_the_frames_edge_sees_the_scene_beyond_it_not_twice_the_light_inside() {
    // A wall (0.2-0.3, a gentle ramp) blurred 6 px, the truth rendered on a frame 20 px wider
    // on every side and cut: the scene goes on beyond the frame. Inside the frame, a lamp 3 px
    // from its left edge (rows 8-9), and a lamp the frame's left edge cuts (rows 40-43: it
    // goes on beyond). Without the guess, the edge averages only the in-frame half of each
    // disk: the inside lamp counts about twice near the edge, the cut lamp half.
    let (w, h, pad) = (48usize, 56usize, 20usize);
    let coc = CocModel::new(12.0, 1.0).unwrap();
    let z = 2.0; // disparity 0.5: CoC 6 px
    let wide = Image::from_fn(w + 2 * pad, h + 2 * pad, |x, y| {
        let (fx, fy) = (x as i64 - pad as i64, y as i64 - pad as i64);
        let inside_lamp = (3..5).contains(&fx) && (8..10).contains(&fy);
        let cut_lamp = (-6..4).contains(&fx) && (40..44).contains(&fy);
        if inside_lamp || cut_lamp {
            [8.0, 8.0, 8.0, 1.0]
        } else {
            let v = 0.2 + 0.1 * x as f32 / (w + 2 * pad) as f32;
            [v, v, v, 1.0]
        }
    });
    let frame = Image::from_fn(w, h, |x, y| wide.get(x + pad, y + pad));
    let truth = job_render(&flat_job(coc, true), &wide, z).without_border(pad).unwrap();
    let guessed = job_render(&flat_job(coc, true), &frame, z);
    let cut = job_render(&flat_job(coc, false), &frame, z);
    assert_eq!((guessed.width, guessed.height), (w, h), "the output is the frame");
    // The error over the 6 columns at the left edge, in the rows each lamp reaches.
    let error = |image: &Image, rows: std::ops::Range<usize>| -> f32 {
        let mut sum = 0.0;
        let mut n = 0.0;
        for y in rows {
            for x in 0..6 {
                let (a, b) = (image.get(x, y), truth.get(x, y));
                sum += (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f32>();
                n += 3.0;
            }
        }
        (sum / n).sqrt()
    };
    for (lamp, rows) in [("inside", 2..16), ("cut", 34..50)] {
        let (with, without) = (error(&guessed, rows.clone()), error(&cut, rows));
        assert!(with < 0.5 * without, "{lamp} lamp: RMSE at the edge {with:.4} with the guess, {without:.4} without");
    }
    // Far from every edge the guess changes nothing.
    for y in 20..30 {
        for x in 20..28 {
            let (a, b) = (guessed.get(x, y), cut.get(x, y));
            assert!((0..4).all(|c| (a[c] - b[c]).abs() < 1e-5), "({x}, {y}): {a:?} vs {b:?}");
        }
    }
}
