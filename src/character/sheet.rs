//! The lens-character contact sheet (README): one procedural bokeh scene rendered with each
//! control, labelled. HDR lights on a far dark wall, an in-focus striped card and a near bar
//! make aperture shape, cat's-eye, fringing, blur multipliers, focus picking and bloom visible
//! at a glance; the last panels are the debug views (CoC map, focus peaking, layers).
use image::{Rgb, RgbImage};

use super::debug::{coc_image, coc_map, layers_image, peaking_overlay};
use super::{Bloom, BlurRemap, CatsEye, Character};
use crate::image::font::{draw_text, GLYPH_H};
use crate::camera::{Aperture, CocModel};
use crate::image::Image;
use crate::render::drbokeh::RenderOptions;
use crate::camera::FocusField;
use crate::render::{Lens, Method, MethodSettings};
use crate::stack::ldr::linear_to_srgb;
use crate::stack::{Layer, LayerStack};
use crate::vk::Context;
use crate::Result;

const PAD: u32 = 4;
const LABEL_H: u32 = GLYPH_H * 2 + 2 * PAD;
const COLUMNS: u32 = 4;

/// The test scene: a 240x160 frame, a dark wall (disparity 0.2) dotted with 3x3 HDR lights, a
/// striped card (disparity 0.5, in focus) on the left third and an orange bar (disparity 0.8)
/// in front on the right.
pub fn bokeh_scene() -> Result<(LayerStack, Lens)> {
    let (w, h) = (240, 160);
    // 3x3 lights centred every 40 px, so an 8-bit copy clipped at 1 still has visible balls.
    let near_light = |v: usize| (v % 40).abs_diff(20) <= 1;
    let wall = Image::from_fn(w, h, |x, y| {
        let v = if near_light(x) && near_light(y) { 25.0 } else { 0.02 };
        [v, v * 0.9, v * 0.8, 1.0]
    });
    let card = Image::from_fn(w, h, |x, y| {
        let inside = x < 80 && (30..130).contains(&y);
        let stripe = if (x / 4) % 2 == 0 { 0.9 } else { 0.1 };
        if inside { [stripe, stripe, stripe, 1.0] } else { [0.0; 4] }
    });
    let bar = Image::from_fn(w, h, |x, _| if (196..204).contains(&x) { [0.9, 0.45, 0.1, 1.0] } else { [0.0; 4] });
    let layers = vec![
        Layer { name: "bar".into(), rgba: bar, disparity: vec![0.8; w * h] },
        Layer { name: "card".into(), rgba: card, disparity: vec![0.5; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.2; w * h] },
    ];
    // Focus on the card; the lights blur to 9 px, the bar to 9 px.
    let lens = Lens { coc: CocModel::new(30.0, 0.5)?, aperture: Aperture::Disk };
    Ok((LayerStack::new(w, h, layers)?, lens))
}

/// The scene as an 8-bit source would hold it: every value clipped to 1.
fn clipped(stack: &LayerStack) -> LayerStack {
    let mut ldr = stack.clone();
    for layer in &mut ldr.layers {
        layer.rgba.pixels.iter_mut().for_each(|p| *p = p.map(|c| c.min(1.0)));
    }
    ldr
}

/// Renders the scene with each control, adds the debug views, and lays the panels out in a
/// labelled grid.
pub fn character_sheet(ctx: &Context) -> Result<RgbImage> {
    let (stack, lens) = bokeh_scene()?;
    let ldr = clipped(&stack);
    let with = |aperture: &str| -> Result<Lens> { Ok(Lens { aperture: Aperture::parse(aperture)?, ..lens.clone() }) };
    let none = Character::default();
    let remap = |remap: BlurRemap| Character { remap, ..none.clone() };
    let cases: Vec<(&str, Character, Lens, &LayerStack)> = vec![
        ("disk", none.clone(), lens.clone(), &stack),
        ("polygon:6", none.clone(), with("polygon:6:rotation=15")?, &stack),
        ("anamorphic:2", none.clone(), with("anamorphic:2")?, &stack),
        ("anamorphic:2 rot=90", none.clone(), with("anamorphic:2:rotation=90")?, &stack),
        ("ring:0.6", none.clone(), with("ring:0.6")?, &stack),
        ("cats-eye 1.0", Character { cats_eye: Some(CatsEye::new(1.0)?), ..none.clone() }, lens.clone(), &stack),
        ("chromatic 2,0,-2", Character { chromatic: Some([2.0, 0.0, -2.0]), ..none.clone() }, lens.clone(), &stack),
        ("near-blur 2", remap(BlurRemap { near: 2.0, ..BlurRemap::default() }), lens.clone(), &stack),
        ("far-blur 0.5", remap(BlurRemap { far: 0.5, ..BlurRemap::default() }), lens.clone(), &stack),
        ("max-blur 4", remap(BlurRemap { max_px: Some(4.0), ..BlurRemap::default() }), lens.clone(), &stack),
        ("focus-at 140,100", Character { focus_at: Some([140, 100]), ..none.clone() }, lens.clone(), &stack),
        ("ldr (clipped at 1)", none.clone(), lens.clone(), &ldr),
        ("ldr + bloom 0.9:16", Character { bloom: Some(Bloom { threshold: 0.9, gain: 16.0 }), ..none.clone() }, lens.clone(), &ldr),
    ];
    let mut panels = Vec::with_capacity(cases.len() + 3);
    let settings = MethodSettings::default();
    for (label, character, lens, stack) in &cases {
        let (image, ..) = character.render(Method::DrBokeh, Some(ctx), stack, lens, &RenderOptions::default(), &settings)?;
        panels.push((label.to_string(), image));
    }
    let plain = &panels[0].1;
    let coc = coc_image(stack.width, stack.height, &coc_map(&stack, &lens, &FocusField::Plane)?);
    let peaking = peaking_overlay(plain);
    panels.extend([("debug: coc map".into(), coc), ("debug: focus peaking".into(), peaking)]);
    panels.push(("debug: layers".into(), layers_image(&stack)));
    Ok(grid(&panels, stack.width as u32, stack.height as u32))
}

/// Labelled panels, [`COLUMNS`] per row, display-encoded (sRGB, clipped to [0, 1]).
fn grid(panels: &[(String, Image)], cell_w: u32, cell_h: u32) -> RgbImage {
    let rows = (panels.len() as u32).div_ceil(COLUMNS);
    let mut sheet = RgbImage::from_pixel(PAD + COLUMNS * (cell_w + PAD), rows * (LABEL_H + cell_h + PAD) + PAD, Rgb([40, 40, 40]));
    for (i, (label, image)) in panels.iter().enumerate() {
        let (col, row) = (i as u32 % COLUMNS, i as u32 / COLUMNS);
        let (x0, y0) = (PAD + col * (cell_w + PAD), PAD + row * (LABEL_H + cell_h + PAD));
        draw_text(&mut sheet, x0, y0 + PAD, label, 2, cell_w, Rgb([235, 235, 235]));
        for (p, pixel) in image.pixels.iter().enumerate() {
            let (x, y) = ((p % image.width) as u32, (p / image.width) as u32);
            let encode = |c: f32| (linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8;
            sheet.put_pixel(x0 + x, y0 + LABEL_H + y, Rgb([encode(pixel[0]), encode(pixel[1]), encode(pixel[2])]));
        }
    }
    sheet
}
