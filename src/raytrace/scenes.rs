//! The built-in scenes: 2 to 5 layers each, covering foreground and background focus, thin
//! structures, HDR highlights, a tilted plane and CoC radii from about 3 to 38 pixels at the
//! native 256 x 192 (radii scale with `TraceOptions::scale`).
//!
//! | scene            | focus      | layers | max CoC px (native) |
//! |------------------|------------|--------|---------------------|
//! | portrait-night   | subject    | 2      | 13.0 |
//! | branches         | background | 3      | 37.7 |
//! | fence            | subject    | 3      | 11.8 |
//! | letters          | middle     | 3      | 10.7 |
//! | fairy-lights     | subject    | 3      | 24.3 |
//! | tilted-wall      | wall centre| 3      | 19.0 |
//! | five-layers      | middle     | 5      | 18.2 |
//! | small-coc        | subject    | 3      |  3.1 |
//! | macro            | foreground | 2      | 36.3 |
//!
//! The table is checked by a test (`tests/raytrace.rs`) against `Scene::coc_range_px`.
use crate::camera::PhysicalCamera;
use crate::{Error, Result};

use super::noise::scatter;
use super::scene::{Scene, Surface, ZPass};
use super::shape::Shape;
use super::strokes::{self, Strokes};
use super::texture::{arc, Checker, Cutout, Lights, Mottled, Opacity, Over, Photo, Rgb, Solid, Stripes, TextureRef};

const WIDTH: usize = 256;
const HEIGHT: usize = 192;

fn camera(focal_length_mm: f32, fstop: f32, focus_distance: f32) -> PhysicalCamera {
    PhysicalCamera { focal_length_mm, sensor_width_mm: 36.0, fstop, focus_distance }
}

fn scene(name: &str, description: &str, camera: PhysicalCamera, surfaces: Vec<Surface>) -> Scene {
    Scene { name: name.into(), description: description.into(), camera, width: WIDTH, height: HEIGHT, surfaces, z_pass: ZPass::PixelCentre }
}

/// All built-in scenes, in a fixed order.
pub fn builtin_scenes() -> Vec<Scene> {
    vec![portrait_night(), branches(), fence(), letters(), fairy_lights(), tilted_wall(), five_layers(), small_coc(), macro_scene()]
}

/// The single-image scenes (issue 22): square 256 x 256 like the held-out Cycles set, each
/// built around one failure of single-image methods seen there. Kept apart from
/// [`builtin_scenes`] (the layered benchmark), found by name all the same. Their depth is
/// Cycles' Z pass, one anti-aliasing sample per pixel ([`ZPass::OneSample`]), so mixed edge
/// pixels sometimes carry the other side's depth, as in the held-out renders.
///
/// | scene           | lens, focus          | planes (m)                | CoC px (256^2)            |
/// |-----------------|----------------------|---------------------------|---------------------------|
/// | silhouette-hdr  | 85 mm f/1.4, 1.5 m   | 1.5, 12                   | 0, 10.7                   |
/// | five-planes     | 85 mm f/1.4, 1.6 m   | 1.0, 1.6, 2.6, 4.0, 12    | 6.9, 0, 4.4, 6.9, 9.9     |
/// | thin-near       | 85 mm f/2, 3 m       | 0.6, 3, 10                | 17.1, 0, 3.0              |
pub fn single_image_scenes() -> Vec<Scene> {
    vec![silhouette_hdr(), five_planes(), thin_near()]
}

/// A built-in scene by name (layered or single-image set); the error lists the valid names.
pub fn builtin_scene(name: &str) -> Result<Scene> {
    let mut scenes = builtin_scenes();
    scenes.extend(single_image_scenes());
    let names: Vec<String> = scenes.iter().map(|s| s.name.clone()).collect();
    scenes
        .into_iter()
        .find(|s| s.name == name)
        .ok_or_else(|| Error::invalid("scene name", format!("no built-in scene '{name}'; available: {}", names.join(", "))))
}

fn dusk_photo(seed: u32) -> TextureRef {
    arc(Photo {
        sky_top: [0.05, 0.07, 0.2],
        sky_horizon: [0.6, 0.3, 0.15],
        ground: [0.12, 0.1, 0.08],
        buildings: [0.08, 0.08, 0.1],
        horizon: 0.25,
        seed,
    })
}

fn day_photo(seed: u32) -> TextureRef {
    arc(Photo {
        sky_top: [0.15, 0.3, 0.75],
        sky_horizon: [0.6, 0.7, 0.85],
        ground: [0.2, 0.3, 0.08],
        buildings: [0.45, 0.4, 0.35],
        horizon: 0.1,
        seed,
    })
}

/// `count` HDR discs scattered over `[u0, u1] x [v0, v1]`, radius in `radius`, brightness
/// 5-50 in warm and cool tints.
fn lights(seed: u32, count: u32, region: [f32; 4], radius: [f32; 2]) -> Lights {
    let tints: [Rgb; 3] = [[1.0, 0.7, 0.35], [0.5, 0.7, 1.0], [1.0, 0.95, 0.9]];
    let discs = (0..count)
        .map(|i| {
            let r = |k: u32| scatter(seed, i * 5 + k);
            let centre = [region[0] + (region[1] - region[0]) * r(0), region[2] + (region[3] - region[2]) * r(1)];
            let size = radius[0] + (radius[1] - radius[0]) * r(2);
            let level = 5.0 + 45.0 * r(3) * r(3);
            let tint = tints[(r(4) * 3.0) as usize % 3];
            (centre, size, tint.map(|c| c * level))
        })
        .collect();
    Lights { discs }
}

/// A head-and-shoulders cut-out with fine hair: the in-focus subject of several scenes.
fn person(centre_u: f32, top_v: f32, size: f32, seed: u32) -> TextureRef {
    let head_c = [centre_u, top_v + 0.13 * size];
    let head_r = [0.09 * size, 0.12 * size];
    let hair = Strokes::new(strokes::hair(head_c, head_r, 140, 0.07 * size, 0.004, seed));
    let skin = arc(Mottled { a: [0.55, 0.32, 0.22], b: [0.75, 0.48, 0.35], frequency: 30.0, seed });
    let cloth = arc(Mottled { a: [0.05, 0.12, 0.3], b: [0.3, 0.1, 0.12], frequency: 12.0, seed: seed + 1 });
    let body = Shape::union(vec![
        Shape::Ellipse { center: [centre_u, top_v + 0.62 * size], radii: [0.28 * size, 0.36 * size] },
        Shape::Rect { min: [centre_u - 0.28 * size, top_v + 0.62 * size], max: [centre_u + 0.28 * size, 10.0] },
    ]);
    arc(Over(vec![
        arc(Cutout { shape: Shape::Strokes(hair), fill: arc(Solid([0.12, 0.07, 0.04, 1.0])) }),
        arc(Cutout { shape: Shape::Ellipse { center: head_c, radii: head_r }, fill: skin }),
        arc(Cutout { shape: Shape::Rect { min: [centre_u - 0.03 * size, head_c[1]], max: [centre_u + 0.03 * size, top_v + 0.35 * size] }, fill: arc(Solid([0.5, 0.3, 0.2, 1.0])) }),
        arc(Cutout { shape: body, fill: cloth }),
    ]))
}

/// Branch cut-outs with small leaves, entering from the frame edges.
fn foliage(seed: u32, leaf: Rgb) -> TextureRef {
    let mut segments = strokes::branches([-1.2, 0.9], -0.9, 0.55, 0.05, 6, seed);
    segments.extend(strokes::branches([1.2, -0.9], 2.4, 0.5, 0.04, 6, seed + 1));
    let leaves: Vec<Shape> = segments
        .iter()
        .filter(|s| s.half_width < 0.004)
        .map(|s| Shape::Ellipse { center: s.b, radii: [0.025, 0.015] })
        .collect();
    let bark = arc(Mottled { a: [0.08, 0.05, 0.03], b: [0.25, 0.17, 0.1], frequency: 40.0, seed });
    arc(Over(vec![
        arc(Cutout { shape: Shape::union(leaves), fill: arc(Mottled { a: leaf, b: leaf.map(|c| c * 0.4), frequency: 60.0, seed }) }),
        arc(Cutout { shape: Shape::Strokes(Strokes::new(segments)), fill: bark }),
    ]))
}

fn portrait_night() -> Scene {
    let cam = camera(135.0, 1.8, 2.5);
    let background = arc(Over(vec![arc(lights(11, 40, [-2.0, 2.0, -1.0, 0.3], [0.015, 0.035])), dusk_photo(1)]));
    scene("portrait-night", "subject in focus, dusk city with HDR lights behind (bokeh balls)", cam, vec![
        Surface::billboard("subject", 2.5, &cam, person(0.1, -0.45, 1.3, 3)),
        Surface::billboard("background", 25.0, &cam, background),
    ])
}

fn branches() -> Scene {
    let cam = camera(85.0, 1.4, 6.0);
    let bench = Shape::union(vec![
        Shape::Rect { min: [-0.9, 0.2], max: [-0.1, 0.26] },
        Shape::Rect { min: [-0.85, 0.26], max: [-0.8, 0.5] },
        Shape::Rect { min: [-0.2, 0.26], max: [-0.15, 0.5] },
    ]);
    let bench = arc(Cutout { shape: bench, fill: arc(Mottled { a: [0.3, 0.15, 0.05], b: [0.5, 0.3, 0.12], frequency: 50.0, seed: 4 }) });
    scene("branches", "background in focus seen through heavily blurred foreground branches", cam, vec![
        Surface::billboard("branches", 0.45, &cam, foliage(21, [0.1, 0.35, 0.05])),
        Surface::billboard("bench", 2.0, &cam, bench),
        Surface::billboard("background", 6.0, &cam, day_photo(2)),
    ])
}

fn fence() -> Scene {
    let cam = camera(85.0, 2.0, 3.0);
    let bars = Strokes::new(strokes::fence(-3.0, 3.0, -0.3, 2.0, 0.09, 0.025));
    let wood = arc(Mottled { a: [0.55, 0.5, 0.45], b: [0.8, 0.78, 0.7], frequency: 20.0, seed: 5 });
    scene("fence", "subject in focus behind a blurred picket fence", cam, vec![
        Surface::billboard("fence", 0.8, &cam, arc(Cutout { shape: Shape::Strokes(bars), fill: wood })),
        Surface::billboard("subject", 3.0, &cam, person(-0.2, -0.55, 1.2, 6)),
        Surface::billboard("background", 12.0, &cam, day_photo(7)),
    ])
}

fn letters() -> Scene {
    let cam = camera(105.0, 2.8, 1.5);
    let text = Strokes::new(strokes::text("LENSBLUR", [-0.78, -0.12], 0.22, 0.03));
    let mut bars: Vec<strokes::Segment> = (0..40)
        .map(|i| {
            let u = -4.0 + 0.2 * i as f32;
            strokes::Segment { a: [u, 0.4], b: [u + 0.1, 3.0], half_width: 0.03 }
        })
        .collect();
    bars.push(strokes::Segment { a: [-4.0, 0.38], b: [4.0, 0.38], half_width: 0.02 });
    let paint = arc(Mottled { a: [0.6, 0.1, 0.08], b: [0.8, 0.3, 0.2], frequency: 15.0, seed: 25 });
    let railing = Cutout { shape: Shape::Strokes(Strokes::new(bars)), fill: paint };
    scene("letters", "cut-out letters in focus between a blurred railing and a checker wall", cam, vec![
        Surface::billboard("railing", 0.7, &cam, arc(railing)),
        Surface::billboard("letters", 1.5, &cam, arc(Cutout { shape: Shape::Strokes(text), fill: arc(Solid([0.9, 0.75, 0.1, 1.0])) })),
        Surface::billboard("wall", 6.0, &cam, arc(Checker { period: 0.16, a: [0.7, 0.7, 0.72], b: [0.1, 0.12, 0.2] })),
    ])
}

fn fairy_lights() -> Scene {
    let cam = camera(135.0, 2.0, 2.0);
    let wire = Strokes::new((0..8).map(|i| {
        let u = -1.3 + 0.33 * i as f32;
        strokes::Segment { a: [u, -0.55 + 0.05 * (i % 2) as f32], b: [u + 0.33, -0.55 + 0.05 * ((i + 1) % 2) as f32], half_width: 0.003 }
    }).collect());
    let bulbs = lights(31, 30, [-1.3, 1.3, -0.6, -0.45], [0.02, 0.035]);
    let string = arc(Over(vec![arc(bulbs), arc(Cutout { shape: Shape::Strokes(wire), fill: arc(Solid([0.02, 0.02, 0.02, 1.0])) })]));
    let background = arc(Over(vec![arc(lights(32, 60, [-2.0, 2.0, -0.8, 0.8], [0.012, 0.025])), dusk_photo(8)]));
    scene("fairy-lights", "subject in focus, HDR light string blurred in front, city lights behind", cam, vec![
        Surface::billboard("light-string", 0.8, &cam, string),
        Surface::billboard("subject", 2.0, &cam, person(0.25, -0.4, 1.1, 9)),
        Surface::billboard("background", 40.0, &cam, background),
    ])
}

fn tilted_wall() -> Scene {
    let cam = camera(200.0, 2.8, 8.0);
    let post = Shape::union(vec![Shape::Rect { min: [-0.62, -2.0], max: [-0.55, 2.0] }, Shape::Ellipse { center: [-0.585, -0.5], radii: [0.06, 0.04] }]);
    let post = Over(vec![arc(Cutout { shape: Shape::Ellipse { center: [-0.585, -0.5], radii: [0.03, 0.02] }, fill: arc(Solid([30.0, 25.0, 15.0, 1.0])) }), arc(Cutout { shape: post, fill: arc(Solid([0.05, 0.06, 0.05, 1.0])) })]);
    let bricks = Over(vec![
        arc(Cutout { shape: Shape::Strokes(Strokes::new(strokes::text("HOTEL", [-0.5, -0.4], 0.12, 0.015))), fill: arc(Solid([0.9, 0.9, 0.85, 1.0])) }),
        arc(Mottled { a: [0.35, 0.12, 0.08], b: [0.6, 0.3, 0.2], frequency: 25.0, seed: 12 }),
    ]);
    // Disparity (1 - 10 tx) / 8 along the image: the wall recedes from ~4 m (left) to ~80 m.
    scene("tilted-wall", "a wall receding to the right, in focus at the centre; subject and lamp post in front", cam, vec![
        Surface::billboard("lamp-post", 2.0, &cam, arc(post)),
        Surface::billboard("subject", 4.0, &cam, person(0.35, -0.3, 0.9, 13)),
        Surface::tilted("wall", 8.0, [-10.0, 0.0], &cam, arc(bricks)),
    ])
}

fn five_layers() -> Scene {
    let cam = camera(105.0, 2.0, 2.0);
    let curtain = Opacity { texture: arc(Cutout { shape: Shape::Rect { min: [0.3, -2.0], max: [3.0, 2.0] }, fill: arc(Stripes { period: 0.06, angle: 0.0, duty: 0.5, a: [0.9, 0.85, 0.7], b: [0.7, 0.6, 0.5] }) }), alpha: 0.45 };
    let sculpture = Cutout { shape: Shape::union(vec![Shape::Ellipse { center: [-0.55, 0.1], radii: [0.18, 0.3] }, Shape::Rect { min: [-0.7, 0.35], max: [-0.4, 2.0] }]), fill: arc(Checker { period: 0.05, a: [0.8, 0.8, 0.8], b: [0.2, 0.25, 0.3] }) };
    let background = Over(vec![arc(lights(41, 25, [-1.5, 1.5, -0.6, 0.2], [0.015, 0.03])), day_photo(42)]);
    scene("five-layers", "Dr.Bokeh-style stack: leaves, a translucent curtain, subject, sculpture, background", cam, vec![
        Surface::billboard("leaves", 0.7, &cam, foliage(43, [0.25, 0.4, 0.05])),
        Surface::billboard("curtain", 1.2, &cam, arc(curtain)),
        Surface::billboard("subject", 2.0, &cam, person(0.0, -0.35, 1.0, 44)),
        Surface::billboard("sculpture", 4.0, &cam, arc(sculpture)),
        Surface::billboard("background", 15.0, &cam, arc(background)),
    ])
}

fn small_coc() -> Scene {
    let cam = camera(85.0, 2.8, 2.0);
    let mesh = Strokes::new(strokes::fence(-2.0, 2.0, -0.2, 2.0, 0.05, 0.012));
    scene("small-coc", "mild blur (CoC about 3 px) on fine detail: a thin mesh, subject, checker", cam, vec![
        Surface::billboard("mesh", 1.2, &cam, arc(Cutout { shape: Shape::Strokes(mesh), fill: arc(Solid([0.8, 0.8, 0.75, 1.0])) })),
        Surface::billboard("subject", 2.0, &cam, person(-0.3, -0.5, 1.0, 51)),
        Surface::billboard("background", 5.0, &cam, arc(Checker { period: 0.04, a: [0.6, 0.55, 0.4], b: [0.15, 0.2, 0.15] })),
    ])
}

fn macro_scene() -> Scene {
    let cam = camera(85.0, 1.4, 0.5);
    let petals: Vec<Shape> = (0..8)
        .map(|i| {
            let phi = i as f32 * std::f32::consts::FRAC_PI_4;
            Shape::Ellipse { center: [0.1 + 0.22 * phi.cos(), -0.05 + 0.22 * phi.sin()], radii: [0.13, 0.13] }
        })
        .collect();
    let stem = strokes::Segment { a: [0.1, 0.0], b: [0.0, 2.0], half_width: 0.012 };
    let flower = Over(vec![
        arc(Cutout { shape: Shape::Ellipse { center: [0.1, -0.05], radii: [0.09, 0.09] }, fill: arc(Mottled { a: [0.6, 0.4, 0.0], b: [0.3, 0.12, 0.0], frequency: 80.0, seed: 61 }) }),
        arc(Cutout { shape: Shape::union(petals), fill: arc(Mottled { a: [0.8, 0.1, 0.3], b: [0.95, 0.5, 0.6], frequency: 30.0, seed: 62 }) }),
        arc(Cutout { shape: Shape::Strokes(Strokes::new(vec![stem])), fill: arc(Solid([0.1, 0.3, 0.05, 1.0])) }),
    ]);
    let background = Over(vec![arc(lights(63, 30, [-1.5, 1.5, -1.0, 1.0], [0.04, 0.08])), day_photo(64)]);
    scene("macro", "close-up flower in focus, far background with highlights: large bokeh balls", cam, vec![
        Surface::billboard("flower", 0.5, &cam, arc(flower)),
        Surface::billboard("background", 50.0, &cam, arc(background)),
    ])
}

/// HDR discs on the outline of [`person`]`(0, top, size)` as a background at any depth sees
/// it (billboards share image coordinates): along the shoulders, beside the neck and around
/// the hair, each a little inside, on or outside the edge in turn.
fn outline_lights(seed: u32, size: f32, top: f32) -> Vec<([f32; 2], f32, Rgb)> {
    let (body_c, body_r) = ([0.0, top + 0.62 * size], [0.28 * size, 0.36 * size]);
    let (head_c, hair_r) = ([0.0, top + 0.13 * size], [0.16 * size, 0.19 * size]);
    let mut points = Vec::new();
    for i in 0..9 {
        let phi = std::f32::consts::PI * (1.12 + 0.76 * i as f32 / 8.0);
        points.push((body_c, body_r, phi));
    }
    for i in 0..5 {
        let phi = std::f32::consts::PI * (0.85 + 1.3 * i as f32 / 4.0);
        points.push((head_c, hair_r, phi));
    }
    let mut discs: Vec<([f32; 2], f32, Rgb)> = points
        .iter()
        .enumerate()
        .map(|(i, &(c, r, phi))| {
            let offset = 0.02 * (i % 3) as f32 - 0.02;
            let centre = [c[0] + (r[0] + offset) * phi.cos(), c[1] + (r[1] + offset) * phi.sin()];
            let level = 10.0 + 30.0 * scatter(seed, i as u32);
            (centre, 0.015 + 0.012 * scatter(seed + 1, i as u32), [1.0, 0.8, 0.55].map(|c| c * level))
        })
        .collect();
    // Beside the neck, on the shoulder line: half hidden, and one mostly hidden.
    let neck_v = top + 0.27 * size;
    discs.push(([-0.06 * size, neck_v], 0.02, [30.0, 26.0, 20.0]));
    discs.push(([0.07 * size, neck_v + 0.03], 0.018, [12.0, 16.0, 25.0]));
    discs
}

fn square(name: &str, description: &str, camera: PhysicalCamera, surfaces: Vec<Surface>) -> Scene {
    Scene { name: name.into(), description: description.into(), camera, width: 256, height: 256, surfaces, z_pass: ZPass::OneSample }
}

/// Failure 1: an in-focus silhouette over a dark, far background whose HDR lights sit right
/// behind and just outside its outline; anti-aliased edge pixels mix the two, and the depth
/// is one jittered sample per pixel (Cycles' Z pass), so some mixed pixels carry the wrong
/// side's depth. As in the held-out renders, lights sit on the outline itself (half hidden,
/// or wholly hidden but for their blur) and the frame cuts some of them.
fn silhouette_hdr() -> Scene {
    let cam = camera(85.0, 1.4, 1.5);
    let (size, top) = (1.25, -0.55);
    let mut near_outline = lights(71, 45, [-0.55, 0.55, -0.75, 0.2], [0.012, 0.03]);
    near_outline.discs.extend(outline_lights(75, size, top));
    let night = arc(Photo { sky_top: [0.01, 0.012, 0.03], sky_horizon: [0.06, 0.035, 0.03], ground: [0.02, 0.018, 0.015], buildings: [0.03, 0.03, 0.04], horizon: 0.3, seed: 73 });
    let background = arc(Over(vec![arc(near_outline), arc(lights(72, 24, [-1.05, 1.05, -1.05, 1.05], [0.01, 0.02])), night]));
    square("silhouette-hdr", "in-focus silhouette, HDR lights just behind its outline on a dark far background", cam, vec![
        Surface::billboard("subject", 1.5, &cam, person(0.0, top, size, 74)),
        Surface::billboard("background", 12.0, &cam, background),
    ])
}

/// Failure 2: five planes whose far two (4 m, 12 m) differ by 3 px of CoC at 256^2 (12 px at
/// 1024^2) and must stay separate layers; blurred bars in front outline nothing.
fn five_planes() -> Scene {
    let cam = camera(85.0, 1.4, 1.6);
    let bars = Strokes::new(strokes::fence(-1.5, 1.5, -2.0, 2.0, 0.55, 0.06));
    let subject = person(-0.2, -0.45, 1.0, 81);
    let pillar = Cutout { shape: Shape::Rect { min: [0.25, -0.6], max: [0.75, 2.0] }, fill: arc(Checker { period: 0.07, a: [0.75, 0.72, 0.65], b: [0.25, 0.2, 0.18] }) };
    let wall = Cutout { shape: Shape::Rect { min: [-2.0, -0.15], max: [0.15, 2.0] }, fill: arc(Stripes { period: 0.05, angle: 0.6, duty: 0.5, a: [0.6, 0.25, 0.15], b: [0.3, 0.1, 0.08] }) };
    let background = Over(vec![arc(lights(82, 30, [-0.85, 0.85, -0.85, 0.3], [0.012, 0.025])), dusk_photo(83)]);
    square("five-planes", "bars 1 m, subject 1.6 m (focus), pillar 2.6 m, wall 4 m, lit city 12 m", cam, vec![
        Surface::billboard("bars", 1.0, &cam, arc(Cutout { shape: Shape::Strokes(bars), fill: arc(Mottled { a: [0.1, 0.1, 0.12], b: [0.3, 0.28, 0.25], frequency: 30.0, seed: 84 }) })),
        Surface::billboard("subject", 1.6, &cam, subject),
        Surface::billboard("pillar", 2.6, &cam, arc(pillar)),
        Surface::billboard("wall", 4.0, &cam, arc(wall)),
        Surface::billboard("background", 12.0, &cam, arc(background)),
    ])
}

/// Failure 3: thin bright wires and twigs far in front of an in-focus subject: a blurred wire
/// must spread into a faint wide band, not stay a crisp line or leave a ghost of itself.
fn thin_near() -> Scene {
    let cam = camera(85.0, 2.0, 3.0);
    let mut wires: Vec<strokes::Segment> = (0..5)
        .map(|i| {
            let v = -0.8 + 0.38 * i as f32;
            strokes::Segment { a: [-2.0, v], b: [2.0, v + 0.25], half_width: 0.006 }
        })
        .collect();
    wires.extend(strokes::branches([1.2, 1.1], 2.5, 0.6, 0.02, 5, 91));
    let wire = arc(Cutout { shape: Shape::Strokes(Strokes::new(wires)), fill: arc(Solid([0.85, 0.8, 0.7, 1.0])) });
    square("thin-near", "thin wires and twigs at 0.6 m in front of an in-focus subject at 3 m", cam, vec![
        Surface::billboard("wires", 0.6, &cam, wire),
        Surface::billboard("subject", 3.0, &cam, person(0.0, -0.5, 1.1, 92)),
        Surface::billboard("background", 10.0, &cam, day_photo(93)),
    ])
}
