//! Image error metrics used by every accuracy claim (docs/DESIGN.md §9):
//! relative RMSE over linear RGB values, and FLIP (NVIDIA's perceptual metric, via
//! `nv-flip`) on the 8-bit sRGB tone-mapped images (the PNG mapping of §8).

use glam::Vec3;

use crate::image::Image;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricError {
    #[error("images differ in size: {0}x{1} vs {2}x{3}")]
    SizeMismatch(u32, u32, u32, u32),
    #[error("the {0} image contains NaN or Inf at pixel ({1}, {2})")]
    NonFinite(&'static str, u32, u32),
}

fn check(a: &Image, b: &Image) -> Result<(), MetricError> {
    if a.width != b.width || a.height != b.height {
        return Err(MetricError::SizeMismatch(a.width, a.height, b.width, b.height));
    }
    if let Some((x, y, _)) = a.first_non_finite() {
        return Err(MetricError::NonFinite("test", x, y));
    }
    if let Some((x, y, _)) = b.first_non_finite() {
        return Err(MetricError::NonFinite("reference", x, y));
    }
    Ok(())
}

/// ‖A − B‖₂ / ‖B‖₂ over all linear RGB values (B is the reference). 0 when both are 0;
/// +∞ is never returned: a black reference with a non-black test gives ‖A‖₂ / ε with
/// ε = 1e-30, which callers see as "huge".
pub fn relative_rmse(test: &Image, reference: &Image) -> Result<f64, MetricError> {
    check(test, reference)?;
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (a, b) in test.pixels.iter().zip(&reference.pixels) {
        let d = *a - *b;
        num += (d.x as f64).powi(2) + (d.y as f64).powi(2) + (d.z as f64).powi(2);
        den += (b.x as f64).powi(2) + (b.y as f64).powi(2) + (b.z as f64).powi(2);
    }
    if num == 0.0 {
        return Ok(0.0);
    }
    Ok((num / den.max(1e-60)).sqrt())
}

/// Mean over pixels of |A − B| / (|B| + ε) per channel, with ε = 1% of the reference's
/// mean so that near-black pixels do not dominate.
pub fn mean_relative_difference(test: &Image, reference: &Image) -> Result<f64, MetricError> {
    check(test, reference)?;
    let eps = (0.01 * reference.mean()).max(1e-12) as f32;
    let s: f64 = test.pixels.iter().zip(&reference.pixels).map(|(a, b)| ((*a - *b).abs() / (b.abs() + Vec3::splat(eps))).element_sum() as f64).sum();
    Ok(s / (3 * test.pixels.len().max(1)) as f64)
}

/// (mean(A) − mean(B)) / mean(B): the signed relative difference of the image means
/// over all pixels and channels (B is the reference; 0 when both means are 0).
pub fn relative_mean_difference(test: &Image, reference: &Image) -> Result<f64, MetricError> {
    check(test, reference)?;
    let (a, b) = (test.mean(), reference.mean());
    if a == b {
        return Ok(0.0);
    }
    Ok((a - b) / b.abs().max(1e-30))
}

/// FLIP statistics of a test image against a reference.
#[derive(Clone, Debug)]
pub struct Flip {
    pub mean: f32,
    /// Weighted 95th percentile of the per-pixel error.
    pub p95: f32,
    pub max: f32,
    /// Per-pixel error in [0, 1], row 0 first.
    pub error_map: Vec<f32>,
    pub width: u32,
    pub height: u32,
}

impl Flip {
    /// The error map in the magma colour scale, as 8-bit RGB.
    pub fn error_map_rgb8(&self) -> Vec<u8> {
        let img = nv_flip::FlipImageFloat::with_data(self.width, self.height, &self.error_map);
        img.apply_color_lut(&nv_flip::magma_lut()).to_vec()
    }
}

/// FLIP of `test` against `reference`, both tone-mapped as sRGB(clamp(exposure · L)).
pub fn flip(test: &Image, reference: &Image, exposure: f32) -> Result<Flip, MetricError> {
    check(test, reference)?;
    Ok(flip_srgb8(&test.to_srgb8(exposure), &reference.to_srgb8(exposure), test.width, test.height))
}

/// FLIP of two 8-bit sRGB RGB images of `width` × `height` (row 0 first).
pub fn flip_srgb8(test: &[u8], reference: &[u8], width: u32, height: u32) -> Flip {
    let r = nv_flip::FlipImageRgb8::with_data(width, height, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width, height, test);
    let map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let mut pool = nv_flip::FlipPool::from_image(&map);
    Flip { mean: pool.mean(), p95: pool.get_percentile(0.95, true), max: pool.max_value(), error_map: map.to_vec(), width, height }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_have_zero_error() {
        let a = Image::from_fn(16, 8, |x, y| Vec3::new(x as f32 / 16.0, y as f32 / 8.0, 0.3));
        assert_eq!(relative_rmse(&a, &a).unwrap(), 0.0);
        assert_eq!(mean_relative_difference(&a, &a).unwrap(), 0.0);
        let f = flip(&a, &a, 1.0).unwrap();
        assert_eq!(f.mean, 0.0);
    }

    #[test]
    fn relative_rmse_scales_as_defined() {
        let b = Image::from_fn(4, 4, |_, _| Vec3::splat(1.0));
        let a = Image::from_fn(4, 4, |_, _| Vec3::splat(1.1));
        assert!((relative_rmse(&a, &b).unwrap() - 0.1).abs() < 1e-6);
        assert!((relative_mean_difference(&a, &b).unwrap() - 0.1).abs() < 1e-6);
        let big = Image::from_fn(4, 4, |x, _| if x == 0 { Vec3::ONE } else { Vec3::ZERO });
        assert!(flip(&big, &b, 1.0).unwrap().mean > 0.1);
        assert!(matches!(relative_rmse(&Image::new(3, 4), &b), Err(MetricError::SizeMismatch(..))));
    }
}
