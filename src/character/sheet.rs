//! The lens-character contact sheet (README): one procedural bokeh scene rendered with each
//! control, labelled. HDR point lights on a far dark wall and an in-focus striped card make
//! aperture shape, cat's-eye, fringing and blur multipliers visible at a glance.
use image::{Rgb, RgbImage};

use super::{BlurRemap, Character, CatsEye};
use crate::bench::font::{draw_text, GLYPH_H};
use crate::camera::{Aperture, CocModel};
use crate::image::Image;
use crate::render::drbokeh::RenderOptions;
use crate::render::{Lens, Method, MethodSettings};
use crate::stack::ldr::linear_to_srgb;
use crate::stack::{Layer, LayerStack};
use crate::vk::Context;
use crate::Result;

const PAD: u32 = 4;
const LABEL_H: u32 = GLYPH_H * 2 + 2 * PAD;

/// The test scene: a 240x160 frame, a dark wall (disparity 0.2) dotted with HDR lights, and a
/// striped card (disparity 0.5, in focus) on the left third.
pub fn bokeh_scene() -> Result<(LayerStack, Lens)> {
    let (w, h) = (240, 160);
    let wall = Image::from_fn(w, h, |x, y| {
        let light = x % 40 == 20 && y % 40 == 20;
        let v = if light { 200.0 } else { 0.02 };
        [v, v * 0.9, v * 0.8, 1.0]
    });
    let card = Image::from_fn(w, h, |x, y| {
        let inside = x < 80 && (30..130).contains(&y);
        let stripe = if (x / 4) % 2 == 0 { 0.9 } else { 0.1 };
        if inside { [stripe, stripe, stripe, 1.0] } else { [0.0; 4] }
    });
    let layers = vec![
        Layer { name: "card".into(), rgba: card, disparity: vec![0.5; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.2; w * h] },
    ];
    // Focus on the card; the lights blur to 9 px.
    let lens = Lens { coc: CocModel::new(30.0, 0.5)?, aperture: Aperture::Disk };
    Ok((LayerStack::new(w, h, layers)?, lens))
}

/// Renders the scene with each control and lays the results out in a labelled grid.
pub fn character_sheet(ctx: &Context) -> Result<RgbImage> {
    let (stack, lens) = bokeh_scene()?;
    let with = |aperture: &str| -> Result<Lens> { Ok(Lens { aperture: Aperture::parse(aperture)?, ..lens.clone() }) };
    let none = Character::default();
    let cases: Vec<(&str, Character, Lens)> = vec![
        ("disk", none.clone(), lens.clone()),
        ("polygon:6", none.clone(), with("polygon:6:rotation=15")?),
        ("anamorphic:2", none.clone(), with("anamorphic:2")?),
        ("ring:0.6", none.clone(), with("ring:0.6")?),
        ("cats-eye 1.0", Character { cats_eye: Some(CatsEye::new(1.0)?), ..none.clone() }, lens.clone()),
        ("chromatic 2,0,-2", Character { chromatic: Some([2.0, 0.0, -2.0]), ..none.clone() }, lens.clone()),
        ("far-blur 0.5", Character { remap: BlurRemap { far: 0.5, ..BlurRemap::default() }, ..none.clone() }, lens.clone()),
        ("max-blur 4", Character { remap: BlurRemap { max_px: Some(4.0), ..BlurRemap::default() }, ..none }, lens.clone()),
    ];
    let columns = 4u32;
    let (cell_w, cell_h) = (stack.width as u32, stack.height as u32);
    let rows = (cases.len() as u32).div_ceil(columns);
    let mut sheet = RgbImage::from_pixel(PAD + columns * (cell_w + PAD), rows * (LABEL_H + cell_h + PAD) + PAD, Rgb([40, 40, 40]));
    for (i, (label, character, lens)) in cases.iter().enumerate() {
        let (image, ..) = character.render(Method::DrBokeh, Some(ctx), &stack, lens, &RenderOptions::default(), &MethodSettings::default())?;
        let (col, row) = (i as u32 % columns, i as u32 / columns);
        let (x0, y0) = (PAD + col * (cell_w + PAD), PAD + row * (LABEL_H + cell_h + PAD));
        draw_text(&mut sheet, x0, y0 + PAD, label, 2, cell_w, Rgb([235, 235, 235]));
        for (p, pixel) in image.pixels.iter().enumerate() {
            let (x, y) = ((p % image.width) as u32, (p / image.width) as u32);
            let encode = |c: f32| (linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8;
            sheet.put_pixel(x0 + x, y0 + LABEL_H + y, Rgb([encode(pixel[0]), encode(pixel[1]), encode(pixel[2])]));
        }
    }
    Ok(sheet)
}
