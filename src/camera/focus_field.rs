//! Where the lens focuses: a plane, a tilted plane (tilt-shift) or several planes. Camera
//! math shared by the methods that render a focus field (vdslr) and the debug views.
use super::CocModel;
use crate::{Error, Result};

/// Where the lens focuses.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum FocusField {
    /// The plane of `CocModel::focus_disparity`.
    #[default]
    Plane,
    /// Tilt-shift: the focus disparity varies linearly across the frame,
    /// `d_f(x, y) = focus_disparity + gradient[0] (x - cx) + gradient[1] (y - cy)` with
    /// `(cx, cy)` the image centre and the gradient in disparity per pixel.
    Tilt { gradient: [f32; 2] },
    /// Several focal planes at once (optically impossible): `CoC = K min_i |d - d_f,i|`, the
    /// sign taken from the nearest plane. `CocModel::focus_disparity` is ignored.
    Planes(Vec<f32>),
}

impl FocusField {
    /// The disparity map edited by the focus field: signed relative disparity `d - d_f(x, y)`
    /// per pixel (positive = nearer than focus): vdslr traces on this map, the debug views
    /// colour it.
    pub fn relative_disparity(&self, disparity: &[f32], width: usize, height: usize, coc: &CocModel) -> Result<Vec<f32>> {
        if disparity.len() != width * height {
            return Err(Error::data(format!("disparity has {} values for a {width}x{height} image", disparity.len())));
        }
        let d_f = coc.focus_disparity;
        let (cx, cy) = ((width as f32 - 1.0) * 0.5, (height as f32 - 1.0) * 0.5);
        match self {
            FocusField::Plane => Ok(disparity.iter().map(|d| d - d_f).collect()),
            FocusField::Tilt { gradient } => Ok(disparity
                .iter()
                .enumerate()
                .map(|(i, d)| d - (d_f + gradient[0] * ((i % width) as f32 - cx) + gradient[1] * ((i / width) as f32 - cy)))
                .collect()),
            FocusField::Planes(planes) => {
                if planes.is_empty() || planes.iter().any(|p| !p.is_finite()) {
                    return Err(Error::invalid("focus field", "focal planes must be a non-empty list of finite disparities"));
                }
                Ok(disparity
                    .iter()
                    .map(|d| planes.iter().map(|p| d - p).fold(f32::INFINITY, |best, s| if s.abs() < best.abs() { s } else { best }))
                    .collect())
            }
        }
    }
}
