//! The in-memory image: RGBA, 32-bit float, linear light, premultiplied alpha, row-major,
//! origin top-left. Every renderer consumes and produces this type.

/// Labels for contact sheets (a 5x7 bitmap font, no font dependency).
pub mod font;

#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 4]>,
}

/// Pixels from which [`Image::new`] zeroes its memory on every core. A render's output frame
/// is allocated from the heap once earlier frames have been freed (glibc's mmap threshold
/// grows with the blocks it frees), and calloc then clears it on one thread: 1.6 ms of a
/// 1024^2 frame's render, as long as the device took for it on an H200.
const PARALLEL_ZEROING_PIXELS: usize = 1 << 18;

impl Image {
    /// A transparent black image.
    pub fn new(width: usize, height: usize) -> Self {
        use rayon::prelude::*;
        let n = width * height;
        let pixels = if n >= PARALLEL_ZEROING_PIXELS {
            (0..n).into_par_iter().map(|_| [0.0; 4]).collect()
        } else {
            vec![[0.0; 4]; n]
        };
        Self { width, height, pixels }
    }

    pub fn filled(width: usize, height: usize, value: [f32; 4]) -> Self {
        Self { width, height, pixels: vec![value; width * height] }
    }

    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> [f32; 4]) -> Self {
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                pixels.push(f(x, y));
            }
        }
        Self { width, height, pixels }
    }

    /// The image less `margin` pixels on every side (an overscanned render cut back to its
    /// frame); `None` when nothing would be left.
    pub fn without_border(&self, margin: usize) -> Option<Image> {
        let (width, height) = (self.width.checked_sub(2 * margin)?, self.height.checked_sub(2 * margin)?);
        (width > 0 && height > 0).then(|| Image::from_fn(width, height, |x, y| self.get(x + margin, y + margin)))
    }

    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        y * self.width + x
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 4] {
        self.pixels[self.index(x, y)]
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, value: [f32; 4]) {
        let i = self.index(x, y);
        self.pixels[i] = value;
    }

    /// Pixel with coordinates clamped to the image (edge extension).
    #[inline]
    pub fn get_clamped(&self, x: i64, y: i64) -> [f32; 4] {
        let xc = x.clamp(0, self.width as i64 - 1) as usize;
        let yc = y.clamp(0, self.height as i64 - 1) as usize;
        self.get(xc, yc)
    }

    /// Flat `f32` view (RGBA interleaved), as uploaded to GPU buffers.
    pub fn as_flat(&self) -> &[f32] {
        bytemuck::cast_slice(&self.pixels)
    }
}
