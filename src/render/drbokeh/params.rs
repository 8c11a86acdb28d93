//! Host-side parameters of one render: validated sizes, the lens in f64, the global bound of
//! the dilation loop, and the area table — everything both the CPU reference and the GPU
//! host code derive from a stack and a lens, computed in one place.
use std::borrow::Cow;
use std::sync::Arc;

use rayon::prelude::*;

use super::kept::KeptTables;
use super::{math, tile_middle, DrBokehPush, LensView, Model, AREA_STEP_PX, AREA_TABLE_RADIUS_PX, TILE, VIGNETTE_AREA_DIRECTIONS, VIGNETTE_AREA_LEVELS, VIGNETTE_BASE_AREA_LEVELS};
use crate::camera::{clipped_centroid, Aperture, Eye, CATS_EYE_SHAPE};
use crate::render::tiler::{rect_push as rect, FrameTiling};
use crate::render::Lens;
use crate::tile_grid::Rect;
use crate::stack::LayerStack;
use crate::{Error, Result};

#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    pub model: Model,
    pub width: usize,
    pub height: usize,
    pub tiles_x: usize,
    pub tiles_y: usize,
    pub layer_count: usize,
    pub lens: LensView,
    /// Largest scatter support or gather radius of any pixel of any layer, in pixels.
    pub max_support: f64,
    /// `A(r)` at `r = i * AREA_STEP_PX`: exact lattice sums of the default model's `S K`
    /// (shared with the other renders through the same aperture).
    pub area_lut: Arc<[f64]>,
    /// A vignetted polygon or ellipse: the centroid of its clipped base at each 16 px tile
    /// ([`clipped_centroid`] at the shift of the tile's middle, `LensView::at_receiver`'s),
    /// row-major; empty for every other lens.
    pub eyes: Vec<[f64; 2]>,
}

impl Params {
    pub fn new(stack: &LayerStack, lens: &Lens, model: Model) -> Result<Self> {
        Self::with_range(stack, lens, model, stack.disparity_range())
    }

    /// [`Self::new`] given the stack's disparity range (smallest, largest; NaN left out), where
    /// the caller has it without another pass over the pixels (a [`super::bounds::StackScan`]).
    pub fn with_range(stack: &LayerStack, lens: &Lens, model: Model, (lo, hi): (f32, f32)) -> Result<Self> {
        if stack.layers.is_empty() {
            return Err(Error::data("Dr.Bokeh needs at least one layer"));
        }
        if stack.width == 0 || stack.height == 0 {
            return Err(Error::data("Dr.Bokeh needs a non-empty image"));
        }
        if stack.width > i32::MAX as usize / 2 || stack.height > i32::MAX as usize / 2 {
            return Err(Error::data("image too large for 32-bit pixel indices"));
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(Error::data("layer disparities must be finite"));
        }
        lens.coc.check_renderable(lo, hi)?;
        let view = LensView::new(&lens.coc, &lens.aperture);
        if view.is_vignetted() && model != Model::DrBokeh {
            return Err(Error::unsupported("a vignetted aperture (one-pass --cats-eye) renders under the default model only"));
        }
        let max_radius = view.signed_radius(lo).abs().max(view.signed_radius(hi).abs());
        let max_support = match model {
            Model::DrBokeh => math::support(max_radius),
            Model::Compat => math::support_compat(max_radius),
        };
        let (tiles_x, tiles_y) = (stack.width.div_ceil(TILE), stack.height.div_ceil(TILE));
        let eyes = match &lens.aperture {
            Aperture::Vignetted { base, .. } if view.is_vignetted_base() => (0..tiles_x * tiles_y)
                .into_par_iter()
                .map(|t| {
                    let [x, y] = tile_middle(t % tiles_x, t / tiles_x, stack.width, stack.height);
                    eye_centroid(base, view.vignette_shift(x, y, stack.width, stack.height))
                })
                .collect::<Result<_>>()?,
            _ => Vec::new(),
        };
        let area_lut = area_table_memo(&view, &lens.aperture);
        Ok(Self {
            model,
            width: stack.width,
            height: stack.height,
            tiles_x,
            tiles_y,
            layer_count: stack.layers.len(),
            lens: view,
            max_support,
            area_lut,
            eyes,
        })
    }

    /// The lens receiver pixel (x, y) gathers through: for a vignetted lens the shape at the
    /// middle of its 16 px tile (so one workgroup of the layer pass shares one shape and its
    /// row bounds; `LensView::at_receiver` for the disk), every other lens its own.
    pub fn receiver_lens(&self, x: usize, y: usize) -> Cow<'_, LensView> {
        if !self.lens.is_vignetted_base() {
            return self.lens.at_receiver(x, y, self.width, self.height);
        }
        let (tx, ty) = (x / TILE, y / TILE);
        let [mx, my] = tile_middle(tx, ty, self.width, self.height);
        let shift = self.lens.vignette_shift(mx, my, self.width, self.height);
        let eye = Eye::new(&self.lens.base, shift, self.eyes[ty * self.tiles_x + tx]);
        Cow::Owned(LensView { eye: Some(eye), ..self.lens.clone() })
    }

    /// Area normalisation of a source of CoC radius `r` under this model (for a vignetted
    /// lens: of a source at the frame centre, see [`Self::area_at`]).
    #[inline]
    pub fn area(&self, r: f64) -> f64 {
        match self.model {
            Model::DrBokeh => math::area_from_lut(self.area_level(0), AREA_STEP_PX, r),
            Model::Compat => math::area_compat(r),
        }
    }

    /// What the tiler needs of the frame: tiles are whole 16x16 search tiles.
    pub(crate) fn tiling(&self) -> FrameTiling {
        FrameTiling::new(self.width, self.height, self.layer_count, TILE)
    }

    /// Area normalisation of a source of CoC radius `r` at pixel (x, y): [`Self::area`] but for
    /// a vignetted lens, whose table holds [`VIGNETTE_AREA_LEVELS`] cat's-eyes from the disk to
    /// the frame corner's shape: linear between the two levels around the source's |a| (its
    /// own position's shape, so each source spreads about its own energy). Mirrors
    /// `drbokeh_area_at` in `glsl/common/drbokeh.glsl`.
    ///
    /// A vignetted polygon or ellipse, whose eye depends on the shift's direction too, has
    /// [`VIGNETTE_BASE_AREA_LEVELS`] levels of [`VIGNETTE_AREA_DIRECTIONS`] tables over half a
    /// symmetry sector: bilinear in (|s|, the direction folded into the half sector).
    pub fn area_at(&self, r: f64, x: usize, y: usize) -> f64 {
        if self.model != Model::DrBokeh || !self.lens.is_vignetted() {
            return self.area(r);
        }
        if self.lens.is_vignetted_base() {
            let shift = self.lens.vignette_shift(x as f64, y as f64, self.width, self.height);
            let (level, direction) = vignette_area_coordinates(&self.lens, shift);
            let (l, d) = (level.floor() as usize, direction.floor() as usize);
            let (l, d) = (l.min(VIGNETTE_BASE_AREA_LEVELS - 2), d.min(VIGNETTE_AREA_DIRECTIONS - 2));
            let (tl, td) = (level - l as f64, direction - d as f64);
            let area = |l: usize, d: usize| math::area_from_lut(self.area_level(l * VIGNETTE_AREA_DIRECTIONS + d), AREA_STEP_PX, r);
            let near = area(l, d) * (1.0 - td) + area(l, d + 1) * td;
            let far = area(l + 1, d) * (1.0 - td) + area(l + 1, d + 1) * td;
            return near * (1.0 - tl) + far * tl;
        }
        let [ax, ay] = self.lens.vignette_centre(x as f64, y as f64, self.width, self.height);
        let top = 0.5 * self.lens.aperture[1];
        let f = if top > 0.0 { ax.hypot(ay) / top * (VIGNETTE_AREA_LEVELS - 1) as f64 } else { 0.0 };
        let level = (f.floor() as usize).min(VIGNETTE_AREA_LEVELS - 2);
        let t = f - level as f64;
        let area = |l: usize| math::area_from_lut(self.area_level(l), AREA_STEP_PX, r);
        area(level) * (1.0 - t) + area(level + 1) * t
    }

    /// Entries of one level of the area table.
    fn area_count(&self) -> usize {
        self.area_lut.len() / area_tables(&self.lens)
    }

    fn area_level(&self, level: usize) -> &[f64] {
        let count = self.area_count();
        &self.area_lut[level * count..(level + 1) * count]
    }

    /// Push constants for a dispatch on `layer` over the whole image (one frame tile).
    pub fn push(&self, layer: usize) -> DrBokehPush {
        let whole = Rect { x0: 0, y0: 0, x1: self.width, y1: self.height };
        self.push_tile(layer, whole, whole)
    }

    /// Push constants for a dispatch on `layer` writing `core` from the uploaded `read` rect.
    pub fn push_tile(&self, layer: usize, core: Rect, read: Rect) -> DrBokehPush {
        DrBokehPush {
            width: self.width as i32,
            height: self.height as i32,
            tiles_x: self.tiles_x as i32,
            tiles_y: self.tiles_y as i32,
            layer: layer as i32,
            layer_count: self.layer_count as i32,
            model: self.model.flag(),
            kernel_size: self.lens.kernel_size as i32,
            k_px: self.lens.k_px as f32,
            focus_disparity: self.lens.focus_disparity as f32,
            max_support: self.max_support as f32,
            area_step: AREA_STEP_PX as f32,
            area_count: self.area_count() as i32,
            leaky_slope: 0.0,
            slot: layer as i32,
            fold: 0,
            aperture: self.lens.aperture.map(|v| v as f32),
            core: rect(core),
            read: rect(read),
        }
    }

    /// The area table as the `area_lut` buffer of `drbokeh_layer.comp`.
    pub fn area_lut_f32(&self) -> Vec<f32> {
        self.area_lut.iter().map(|&a| a as f32).collect()
    }

    /// The kernel image as the `kernel` buffer (one dummy element when there is none, since
    /// Vulkan buffers cannot be empty).
    pub fn kernel_f32(&self) -> Vec<f32> {
        if self.lens.kernel.is_empty() {
            vec![0.0]
        } else {
            self.lens.kernel.iter().map(|&w| w as f32).collect()
        }
    }
}

/// [`area_table`] of the lens, kept for the renders that follow ([`KeptTables`]): it does not
/// depend on the focus or the CoC scale (the sums run over radii, not disparities), so a
/// session refocusing or a shot's frames share their aperture's. Made afresh, it took 1 ms of
/// every render through a disk (half of a 1024^2 frame's preparation on a GPU) and 80 ms
/// through a vignetted polygon. The key is the lens less its focus and CoC scale.
fn area_table_memo(lens: &LensView, aperture: &Aperture) -> Arc<[f64]> {
    static TABLES: KeptTables<(LensView, Aperture), [f64]> = KeptTables::new();
    let key = (LensView { k_px: 0.0, focus_disparity: 0.0, ..lens.clone() }, aperture.clone());
    TABLES.get_or_make(key, || area_table(lens, aperture).into())
}

/// `A(r) = sum over integer offsets o of S(r, gauge(o)) K(o, r)`: the exact discrete energy of
/// a source's footprint, so a source of tabulated radius spreads exactly its own energy. The
/// lattice is symmetric under `o -> -o`, so the near-source mirror does not change the sum.
///
/// A vignetted lens gets [`VIGNETTE_AREA_LEVELS`] tables one after the other: the cat's-eyes
/// with |a| from 0 (the disk) to the frame corner's `strength / 2`, each with its centre on
/// the u axis (the lattice's small anisotropy is ignored: the continuous areas are exactly
/// rotation-invariant).
///
/// A vignetted polygon or ellipse gets [`VIGNETTE_BASE_AREA_LEVELS`] levels of
/// [`VIGNETTE_AREA_DIRECTIONS`] tables: its
/// clipped and recentred base ([`Eye`]) with the shift at |s| from 0 to the corner's
/// `strength` and directions over half a symmetry sector from the first edge normal (or the
/// long axis), level-major (`vignette_area_coordinates`).
fn area_table(lens: &LensView, aperture: &Aperture) -> Vec<f64> {
    if !lens.is_vignetted() {
        return area_table_of(lens);
    }
    if let (true, Aperture::Vignetted { base, strength }) = (lens.is_vignetted_base(), aperture) {
        let half_sector = std::f64::consts::PI / symmetry(lens);
        let mut tables: Vec<Option<Vec<f64>>> = (0..VIGNETTE_BASE_AREA_LEVELS * VIGNETTE_AREA_DIRECTIONS)
            .into_par_iter()
            .map(|i| {
                let (level, direction) = (i / VIGNETTE_AREA_DIRECTIONS, i % VIGNETTE_AREA_DIRECTIONS);
                let length = *strength as f64 * level as f64 / (VIGNETTE_BASE_AREA_LEVELS - 1) as f64;
                let angle = lens.base[1] + half_sector * direction as f64 / (VIGNETTE_AREA_DIRECTIONS - 1) as f64;
                let shift = [length * angle.cos(), length * angle.sin()];
                let centroid = clipped_centroid(base, shift)?.centroid;
                Some(area_table_of(&LensView { eye: Some(Eye::new(&lens.base, shift, centroid)), ..lens.clone() }))
            })
            .collect();
        // A shift that lets no light through (a narrow ellipse shifted across its short axis
        // further than any frame position of this aspect ratio reaches: the tiles' own eyes
        // are checked in `Params::new`) keeps the level below's table (level 0 is the base).
        for i in VIGNETTE_AREA_DIRECTIONS..tables.len() {
            if tables[i].is_none() {
                tables[i] = tables[i - VIGNETTE_AREA_DIRECTIONS].clone();
            }
        }
        return tables.into_iter().flatten().flatten().collect();
    }
    let top = 0.5 * lens.aperture[1];
    (0..VIGNETTE_AREA_LEVELS)
        .flat_map(|level| {
            let a = top * level as f64 / (VIGNETTE_AREA_LEVELS - 1) as f64;
            area_table_of(&LensView { aperture: [CATS_EYE_SHAPE as f64, a, 0.0, 0.0], ..lens.clone() })
        })
        .collect()
}

/// How many area tables a lens has: one, a vignetted disk's levels, or a vignetted polygon's or
/// ellipse's levels times directions.
fn area_tables(lens: &LensView) -> usize {
    match (lens.is_vignetted(), lens.is_vignetted_base()) {
        (_, true) => VIGNETTE_BASE_AREA_LEVELS * VIGNETTE_AREA_DIRECTIONS,
        (true, false) => VIGNETTE_AREA_LEVELS,
        _ => 1,
    }
}

/// Turns of a vignetted base's symmetry: its blades, or 2 for the ellipse.
fn symmetry(lens: &LensView) -> f64 {
    if lens.base[0] >= 3.0 { lens.base[0] } else { 2.0 }
}

/// Where a shift falls in a vignetted polygon's or ellipse's area tables, as fractional
/// (level, direction) indices: |s| over the corner's strength, and the direction from the first
/// edge normal (or long axis) folded into half a symmetry sector (the base is symmetric about
/// that axis and repeats every sector). Mirrors `drbokeh_area_at` in `glsl/common/drbokeh.glsl`.
pub fn vignette_area_coordinates(lens: &LensView, shift: [f64; 2]) -> (f64, f64) {
    let (length, top) = (shift[0].hypot(shift[1]), lens.aperture[1]);
    let level = if top > 0.0 { length / top * (VIGNETTE_BASE_AREA_LEVELS - 1) as f64 } else { 0.0 };
    let sector = std::f64::consts::TAU / symmetry(lens);
    let angle = if length > 0.0 { (shift[1].atan2(shift[0]) - lens.base[1]).rem_euclid(sector) } else { 0.0 };
    let folded = angle.min(sector - angle).clamp(0.0, 0.5 * sector);
    (level, folded / (0.5 * sector) * (VIGNETTE_AREA_DIRECTIONS - 1) as f64)
}

/// [`clipped_centroid`], refused where no light passes.
fn eye_centroid(base: &Aperture, shift: [f64; 2]) -> Result<[f64; 2]> {
    clipped_centroid(base, shift)
        .map(|shape| shape.centroid)
        .ok_or_else(|| Error::invalid("cats-eye", "cat's-eye vignetting is so strong that no light passes the aperture"))
}

fn area_table_of(lens: &LensView) -> Vec<f64> {
    let count = (AREA_TABLE_RADIUS_PX / AREA_STEP_PX).round() as usize + 1;
    // On every core: the sums grow with the cube of the radius, and one thread's table was
    // most of a preview frame's preparation (~1 ms, against 0.2 ms of device time at 256^2).
    (0..count)
        .into_par_iter()
        .map(|i| {
            let r = i as f64 * AREA_STEP_PX;
            let half = math::support(r).ceil() as i64;
            let mut sum = 0.0;
            for oy in -half..=half {
                for ox in -half..=half {
                    let (g, k) = lens.lens(ox as f64, oy as f64, r, -1.0);
                    sum += math::scatter(r, g) * k;
                }
            }
            sum.max(f64::MIN_POSITIVE)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CocModel;
    use crate::image::Image;
    use crate::stack::Layer;

    /// A kept area table is the one the lens would make afresh, shared by renders that differ
    /// only in focus and CoC scale, and never handed to another aperture.
    #[test]
    fn kept_area_tables_are_the_apertures_own() {
        let stack = LayerStack::new(8, 8, vec![Layer { name: "l".into(), rgba: Image::new(8, 8), disparity: vec![0.3; 64] }]).unwrap();
        let shapes = ["disk", "polygon:6", "polygon:6:rotation=10", "ring:0.5", "anamorphic:1.7"];
        let mut apertures: Vec<(String, Aperture)> = shapes.iter().map(|&name| (name.to_string(), Aperture::parse(name).unwrap())).collect();
        // Vignetted (cat's-eye) disks and polygons: tables of their own per strength.
        for (name, strength) in [("disk", 0.4), ("polygon:6", 0.4), ("polygon:6", 0.6)] {
            let vignetted = Aperture::vignetted(&Aperture::parse(name).unwrap(), strength).unwrap();
            apertures.push((format!("{name} vignetted {strength}"), vignetted));
        }
        // More apertures than are kept, twice over, each at two focus distances and CoC scales.
        for _round in 0..2 {
            for (name, aperture) in &apertures {
                let aperture = aperture.clone();
                let mut shared = None;
                for (k, focus) in [(12.0, 0.5), (30.0, 0.1)] {
                    let lens = Lens { coc: CocModel::new(k, focus).unwrap(), aperture: aperture.clone() };
                    let params = Params::new(&stack, &lens, Model::DrBokeh).unwrap();
                    let fresh = area_table(&params.lens, &aperture);
                    assert_eq!(&params.area_lut[..], &fresh[..], "{name}, k {k}");
                    match &shared {
                        None => shared = Some(params.area_lut.clone()),
                        Some(first) => assert!(Arc::ptr_eq(first, &params.area_lut), "{name}: one table for every focus"),
                    }
                }
            }
        }
    }
}
