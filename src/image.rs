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

/// Items from which [`filled_vec`] fills on every core. A render's output frame is allocated
/// from the heap once earlier frames have been freed (glibc's mmap threshold grows with the
/// blocks it frees), and calloc then clears it on one thread: 1.6 ms of a 1024^2 frame's
/// render, as long as the device took for it on an H200. Where calloc gets fresh pages from
/// the kernel it clears nothing, and the pages are faulted in where they are first written:
/// filling those costs the writes. So this is for frames, which renders of one size allocate
/// again and again, and not for the backward's 120 MB of gradients at 1024^2 five layers
/// (filled on every core, its preparation grew by 65 ms on lavapipe, and its read-back, where
/// the pages were first touched, fell by only 55 ms).
const PARALLEL_FILL_ITEMS: usize = 1 << 18;

/// `vec![value; n]`, written on every core when it is large (256K items and more).
pub fn filled_vec<T: Copy + Send + Sync>(value: T, n: usize) -> Vec<T> {
    use rayon::prelude::*;
    if n >= PARALLEL_FILL_ITEMS {
        (0..n).into_par_iter().map(|_| value).collect()
    } else {
        vec![value; n]
    }
}

impl Image {
    /// A transparent black image.
    pub fn new(width: usize, height: usize) -> Self {
        Self::filled(width, height, [0.0; 4])
    }

    pub fn filled(width: usize, height: usize, value: [f32; 4]) -> Self {
        Self { width, height, pixels: filled_vec(value, width * height) }
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
