//! The contact sheet: one block per scene, with a header naming the columns.
//! Top row of a block: pinhole input, ground truth, each method's render (PSNR captioned).
//! Bottom row: the pinhole disparity, a legend of the error colours, and each method's
//! absolute-error heat map (mean |error| over R,G,B of the display-encoded images).
use std::path::Path;

use image::{Rgb, RgbImage};

use lensblur::image::font::{advance, draw_text, GLYPH_H};
use super::runner::BenchReport;
use lensblur::image::Image;
use lensblur::metrics::display_encode;
use lensblur::raytrace::GroundTruth;
use lensblur::{Error, Result};

/// Display-encoded absolute error mapped to the top of the heat scale (white).
pub const HEAT_MAX: f32 = 0.25;
/// Thumbnails are shrunk by an integer factor until at most this wide.
const TILE_MAX_WIDTH: usize = 256;
const PAD: u32 = 4;
const BACKGROUND: Rgb<u8> = Rgb([40, 40, 40]);
const INK: Rgb<u8> = Rgb([235, 235, 235]);

/// A displayable thumbnail (8-bit sRGB).
struct Tile {
    width: u32,
    height: u32,
    rgb: Vec<[f32; 3]>,
}

/// Cell size, label height and text scale shared by every block of a sheet.
struct Layout {
    cell_w: u32,
    cell_h: u32,
    /// Text scale: 2 where a cell holds 12 such characters, else 1.
    scale: u32,
    label_h: u32,
    columns: u32,
}

impl Layout {
    fn new(scenes: &[GroundTruth], factors: &[usize], methods: usize) -> Self {
        let cell_w = scenes.iter().zip(factors).map(|(s, f)| s.pinhole.width / f).max().unwrap_or(1) as u32;
        let cell_h = scenes.iter().zip(factors).map(|(s, f)| s.pinhole.height / f).max().unwrap_or(1) as u32;
        let scale = if cell_w >= 12 * advance(2) { 2 } else { 1 };
        Self { cell_w, cell_h, scale, label_h: GLYPH_H * scale + 2 * PAD, columns: 2 + methods as u32 }
    }

    fn block_h(&self) -> u32 {
        self.label_h + 2 * (self.cell_h + PAD)
    }

    fn width(&self) -> u32 {
        PAD + self.columns * (self.cell_w + PAD)
    }

    /// Top-left corner of a tile: `row` 0 = renders, 1 = disparity and errors.
    fn cell(&self, top: u32, col: u32, row: u32) -> (u32, u32) {
        (PAD + col * (self.cell_w + PAD), top + self.label_h + row * (self.cell_h + PAD))
    }
}

/// Builds the sheet for `scenes` and the renders kept in `report` (same order as the run).
pub fn contact_sheet(scenes: &[GroundTruth], report: &BenchReport) -> Result<RgbImage> {
    if report.renders.len() != scenes.len() || report.renders.iter().any(|r| r.len() != report.methods.len()) {
        return Err(Error::data("the contact sheet needs the scenes and renders of the same benchmark run"));
    }
    let factors: Vec<usize> = scenes.iter().map(|s| s.pinhole.width.div_ceil(TILE_MAX_WIDTH).max(1)).collect();
    let layout = Layout::new(scenes, &factors, report.methods.len());
    let height = layout.label_h + scenes.len() as u32 * layout.block_h();
    let mut sheet = RgbImage::from_pixel(layout.width(), height, BACKGROUND);
    let mut headers = vec!["PINHOLE".to_string(), "TRUTH".to_string()];
    headers.extend(report.methods.iter().map(|m| m.name.to_uppercase()));
    for (col, header) in headers.iter().enumerate() {
        draw_text(&mut sheet, PAD + col as u32 * (layout.cell_w + PAD), PAD, header, layout.scale, layout.cell_w, INK);
    }
    for (s, truth) in scenes.iter().enumerate() {
        let top = layout.label_h + s as u32 * layout.block_h();
        draw_scene(&mut sheet, &layout, top, truth, report, s, factors[s]);
    }
    Ok(sheet)
}

fn draw_scene(sheet: &mut RgbImage, layout: &Layout, top: u32, truth: &GroundTruth, report: &BenchReport, s: usize, f: usize) {
    let scale = layout.scale;
    draw_text(sheet, PAD, top + PAD, &format!("SCENE {}", truth.name), scale, layout.width() - PAD, INK);
    place(sheet, &shrink(&display_tile(&truth.pinhole), f), layout.cell(top, 0, 0));
    place(sheet, &shrink(&display_tile(&truth.defocused), f), layout.cell(top, 1, 0));
    place(sheet, &shrink(&disparity_tile(truth), f), layout.cell(top, 0, 1));
    caption(sheet, layout.cell(top, 0, 1), "DISPARITY", layout.cell_w, scale);
    place(sheet, &legend_tile(layout.cell_w, layout.cell_h), layout.cell(top, 1, 1));
    caption(sheet, layout.cell(top, 1, 1), &format!("ERR 0-{HEAT_MAX}"), layout.cell_w, scale);
    for (m, render) in report.renders[s].iter().enumerate() {
        let col = 2 + m as u32;
        place(sheet, &shrink(&display_tile(render), f), layout.cell(top, col, 0));
        place(sheet, &shrink(&heat_tile(render, &truth.defocused), f), layout.cell(top, col, 1));
        let name = &report.methods[m].name;
        if let Some(case) = report.cases.iter().find(|c| c.scene == truth.name && &c.method == name) {
            let psnr = case.metrics.psnr;
            let text = if psnr.is_finite() { format!("{psnr:.1} DB") } else { "INF DB".into() };
            caption(sheet, layout.cell(top, col, 0), &text, layout.cell_w, scale);
        }
    }
}

/// Writes the sheet as PNG.
pub fn write_png(sheet: &RgbImage, path: &Path) -> Result<()> {
    sheet.save_with_format(path, image::ImageFormat::Png).map_err(|e| Error::input(path, format!("cannot write PNG: {e}")))
}

fn display_tile(image: &Image) -> Tile {
    let d = display_encode(image);
    Tile { width: d.width as u32, height: d.height as u32, rgb: d.rgb }
}

fn disparity_tile(truth: &GroundTruth) -> Tile {
    let disparity: Vec<f32> = truth.pinhole_depth.iter().map(|&z| lensblur::camera::disparity_from_z(z)).collect();
    // Stretched to the scene's own range (white = nearest) so layers are told apart.
    let (lo, hi) = disparity.iter().fold((f32::INFINITY, 0.0f32), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    let rgb = disparity.iter().map(|&d| [if hi > lo { (d - lo) / (hi - lo) } else { 0.0 }; 3]).collect();
    Tile { width: truth.pinhole.width as u32, height: truth.pinhole.height as u32, rgb }
}

fn heat_tile(result: &Image, truth: &Image) -> Tile {
    let (a, b) = (display_encode(result), display_encode(truth));
    let rgb = a.rgb.iter().zip(&b.rgb).map(|(p, q)| heat(((0..3).map(|c| (p[c] - q[c]).abs()).sum::<f32>() / 3.0) / HEAT_MAX)).collect();
    Tile { width: a.width as u32, height: a.height as u32, rgb }
}

/// Black -> red -> yellow -> white over t in [0, 1].
fn heat(t: f32) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) * 3.0;
    [t.min(1.0), (t - 1.0).clamp(0.0, 1.0), (t - 2.0).clamp(0.0, 1.0)]
}

/// The error scale as a horizontal ramp from 0 (left) to `HEAT_MAX` (right).
fn legend_tile(width: u32, height: u32) -> Tile {
    let rgb = (0..width * height).map(|i| heat((i % width) as f32 / (width.max(2) - 1) as f32)).collect();
    Tile { width, height, rgb }
}

/// Box-filters by an integer factor (thumbnails only; metrics use the full images).
fn shrink(tile: &Tile, factor: usize) -> Tile {
    let f = factor as u32;
    let (w, h) = (tile.width / f, tile.height / f);
    let mut rgb = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 3];
            for sy in y * f..(y + 1) * f {
                for sx in x * f..(x + 1) * f {
                    let p = tile.rgb[(sy * tile.width + sx) as usize];
                    (0..3).for_each(|c| sum[c] += p[c]);
                }
            }
            rgb.push(sum.map(|s| s / (f * f) as f32));
        }
    }
    Tile { width: w, height: h, rgb }
}

fn place(sheet: &mut RgbImage, tile: &Tile, (x0, y0): (u32, u32)) {
    for y in 0..tile.height {
        for x in 0..tile.width {
            let p = tile.rgb[(y * tile.width + x) as usize].map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
            if x0 + x < sheet.width() && y0 + y < sheet.height() {
                sheet.put_pixel(x0 + x, y0 + y, Rgb(p));
            }
        }
    }
}

/// Text on a dark strip at the top-left of a tile, readable over any image.
fn caption(sheet: &mut RgbImage, (x0, y0): (u32, u32), text: &str, max_width: u32, scale: u32) {
    let w = (text.chars().count() as u32 * advance(scale) + 2).min(max_width);
    for y in y0..(y0 + GLYPH_H * scale + 4).min(sheet.height()) {
        for x in x0..(x0 + w).min(sheet.width()) {
            sheet.put_pixel(x, y, Rgb([0, 0, 0]));
        }
    }
    draw_text(sheet, x0 + 2, y0 + 2, text, scale, max_width - 2, INK);
}
