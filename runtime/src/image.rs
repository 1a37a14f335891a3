//! Linear-RGB images and their files (docs/DESIGN.md §8).
//!
//! - EXR holds linear radiance (RGB, f32).
//! - PNG holds sRGB(clamp(exposure · L)), 8 bits per channel. Goldens and FLIP
//!   comparisons use the same mapping.
//!
//! Writers refuse images with NaN or Inf in them, naming the first bad pixel: a broken
//! render must fail loudly, not be saved as black.

use std::path::{Path, PathBuf};

use glam::Vec3;

/// A linear RGB image, row 0 at the top, x fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    #[error("{path}: cannot encode or decode PNG: {error}")]
    Png { path: PathBuf, error: image::ImageError },
    #[error("{path}: cannot encode or decode EXR: {error}")]
    Exr { path: PathBuf, error: exr::error::Error },
    #[error("{path}: unknown image extension (use .exr or .png)")]
    UnknownFormat { path: PathBuf },
    #[error("{path}: pixel ({x}, {y}) is {value} (NaN or Inf); refusing to write a broken image")]
    NonFinite { path: PathBuf, x: u32, y: u32, value: Vec3 },
    #[error("{path}: image is {width}x{height}, which is empty or too large (at most 65536 per side and {MAX_IMAGE_PIXELS} pixels)")]
    BadSize { path: PathBuf, width: usize, height: usize },
}

/// Most pixels an image read may hold (1.6 GB of linear RGB): a 16384×8192 environment.
pub const MAX_IMAGE_PIXELS: usize = 1 << 27;

fn image_size_ok(w: usize, h: usize) -> bool {
    w > 0 && h > 0 && w <= 65536 && h <= 65536 && w * h <= MAX_IMAGE_PIXELS
}

impl Image {
    pub fn new(width: u32, height: u32) -> Image {
        Image { width, height, pixels: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> Vec3) -> Image {
        let mut pixels = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                pixels.push(f(x, y));
            }
        }
        Image { width, height, pixels }
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    #[inline]
    pub fn set(&mut self, x: u32, y: u32, v: Vec3) {
        self.pixels[(y * self.width + x) as usize] = v;
    }

    /// The mean of each `factor`×`factor` block (a box filter); the size is divided by
    /// `factor`, rounding down (a partial block at the right or bottom is dropped).
    pub fn box_downsample(&self, factor: u32) -> Image {
        let f = factor.max(1);
        let (w, h) = (self.width / f, self.height / f);
        let inv = 1.0 / (f * f) as f32;
        Image::from_fn(w, h, |x, y| {
            let mut sum = Vec3::ZERO;
            for dy in 0..f {
                for dx in 0..f {
                    sum += self.get(x * f + dx, y * f + dy);
                }
            }
            sum * inv
        })
    }

    /// Mean over all pixels and channels.
    pub fn mean(&self) -> f64 {
        let s: f64 = self.pixels.iter().map(|p| (p.x + p.y + p.z) as f64).sum();
        s / (3 * self.pixels.len().max(1)) as f64
    }

    /// The first non-finite pixel, if any.
    pub fn first_non_finite(&self) -> Option<(u32, u32, Vec3)> {
        self.pixels.iter().position(|p| !p.is_finite()).map(|i| (i as u32 % self.width, i as u32 / self.width, self.pixels[i]))
    }

    /// sRGB(clamp(exposure · L)) as 8-bit RGB, row 0 first.
    pub fn to_srgb8(&self, exposure: f32) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| (*p * exposure).to_array().map(|c| (srgb_encode(c) * 255.0 + 0.5) as u8)).collect()
    }

    /// Writes by extension: `.exr` (linear) or `.png` (sRGB of exposure · L).
    pub fn write(&self, path: &Path, exposure: f32) -> Result<(), ImageError> {
        if let Some((x, y, value)) = self.first_non_finite() {
            return Err(ImageError::NonFinite { path: path.into(), x, y, value });
        }
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|error| ImageError::Io { path: dir.into(), error })?;
        }
        match extension(path).as_deref() {
            Some("png") => write_png_rgb8(path, &self.to_srgb8(exposure), self.width, self.height),
            Some("exr") => {
                let w = self.width as usize;
                exr::prelude::write_rgb_file(path, w, self.height as usize, |x, y| {
                    let p = self.pixels[y * w + x];
                    (p.x, p.y, p.z)
                })
                .map_err(|error| ImageError::Exr { path: path.into(), error })
            }
            _ => Err(ImageError::UnknownFormat { path: path.into() }),
        }
    }

    /// Reads `.exr` (linear RGB) or `.png` (decoded from sRGB to linear, then divided
    /// by `exposure` so that writing and reading with the same exposure round-trips).
    pub fn read(path: &Path, exposure: f32) -> Result<Image, ImageError> {
        match extension(path).as_deref() {
            Some("png") => {
                let img = image::open(path).map_err(|error| ImageError::Png { path: path.into(), error })?.to_rgb8();
                let (w, h) = img.dimensions();
                let inv = if exposure > 0.0 { 1.0 / exposure } else { 1.0 };
                let pixels = img.pixels().map(|p| Vec3::new(srgb_decode(p[0] as f32 / 255.0), srgb_decode(p[1] as f32 / 255.0), srgb_decode(p[2] as f32 / 255.0)) * inv).collect();
                Ok(Image { width: w, height: h, pixels })
            }
            Some("exr") => {
                // The header first: the pixels are allocated from its data window, so a
                // tiny file claiming 30000×30000 would otherwise ask for 10 GB.
                let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|error| ImageError::Exr { path: path.into(), error })?;
                for header in &meta.headers {
                    let (w, h) = (header.layer_size.width(), header.layer_size.height());
                    if !image_size_ok(w, h) {
                        return Err(ImageError::BadSize { path: path.into(), width: w, height: h });
                    }
                }
                let img = exr::image::read::read_first_rgba_layer_from_file(
                    path,
                    |res, _| (res.width(), res.height(), vec![Vec3::ZERO; res.width() * res.height()]),
                    |(w, _, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = Vec3::new(r, g, b),
                )
                .map_err(|error| ImageError::Exr { path: path.into(), error })?;
                let (w, h, pixels) = img.layer_data.channel_data.pixels;
                if !image_size_ok(w, h) {
                    return Err(ImageError::BadSize { path: path.into(), width: w, height: h });
                }
                Ok(Image { width: w as u32, height: h as u32, pixels })
            }
            _ => Err(ImageError::UnknownFormat { path: path.into() }),
        }
    }
}

fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase())
}

/// Writes 8-bit RGB rows as a PNG. Encoded in memory and written with one call whose
/// error is returned: `image::save_buffer` writes through a `BufWriter` whose final
/// flush fails silently on drop (a full disk gave a truncated file and "wrote").
pub fn write_png_rgb8(path: &Path, rgb: &[u8], width: u32, height: u32) -> Result<(), ImageError> {
    use image::ImageEncoder;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|error| ImageError::Png { path: path.into(), error })?;
    std::fs::write(path, bytes).map_err(|error| ImageError::Io { path: path.into(), error })
}

/// Linear → sRGB transfer, with clamping to [0, 1] (NaN → 0).
#[inline]
pub fn srgb_encode(c: f32) -> f32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    if c <= 0.0031308 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

/// sRGB → linear transfer.
#[inline]
pub fn srgb_decode(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_is_exact_and_png_within_quantization() {
        let dir = std::env::temp_dir().join(format!("fabric-image-{}", std::process::id()));
        let img = Image::from_fn(7, 5, |x, y| Vec3::new(x as f32 * 0.1, y as f32 * 0.2, 0.5));
        img.write(&dir.join("a.exr"), 1.0).unwrap();
        assert_eq!(Image::read(&dir.join("a.exr"), 1.0).unwrap(), img);
        img.write(&dir.join("a.png"), 1.0).unwrap();
        let back = Image::read(&dir.join("a.png"), 1.0).unwrap();
        for (a, b) in img.pixels.iter().zip(&back.pixels) {
            let a = a.min(Vec3::ONE);
            assert!((a - *b).abs().max_element() < 0.01, "{a} vs {b}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_png_that_cannot_be_written_is_an_error() {
        // /dev/full accepts the open and fails every write (ENOSPC): the error must
        // reach the caller, not be dropped with a buffered writer.
        let full = Path::new("/dev/full");
        let dir = std::env::temp_dir().join(format!("fabric-image-full-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let link = dir.join("x.png");
        let _ = std::fs::remove_file(&link);
        if full.exists() && std::os::unix::fs::symlink(full, &link).is_ok() {
            let err = Image::new(4, 4).write(&link, 1.0).unwrap_err();
            assert!(matches!(err, ImageError::Io { .. }), "{err}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn non_finite_pixels_are_refused() {
        let mut img = Image::new(3, 2);
        img.set(2, 1, Vec3::new(0.0, f32::NAN, 0.0));
        let err = img.write(Path::new("/nonexistent/x.png"), 1.0).unwrap_err();
        assert!(matches!(err, ImageError::NonFinite { x: 2, y: 1, .. }), "{err}");
    }

    #[test]
    fn srgb_transfer_inverts() {
        for i in 0..=100 {
            let c = i as f32 / 100.0;
            assert!((srgb_decode(srgb_encode(c)) - c).abs() < 1e-5);
        }
        assert_eq!(srgb_encode(f32::NAN), 0.0);
        assert!((srgb_encode(7.0) - 1.0).abs() < 1e-6);
    }
}
