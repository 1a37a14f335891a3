//! Per-texel feature vectors for clustering (paper §5.3.1, Eqs. 5–7):
//! y_j = [n_j, t_j, w · f_j].
//!
//! - n_j: the texel's unit normal (3 values).
//! - t_j: the tangent as an *axis* (t ≡ −t), through its axis tensor t tᵀ: the three
//!   values (t_x² − t_y², 2 t_x t_y, 2 t_z·|t_xy|) are continuous in t and even in its
//!   sign, so opposite tangents cluster together.
//! - f_j: the texel's training radiance, RGB, at each of the m configurations.
//!   Departure from the paper: f_j is used at the configurations' world directions
//!   rather than resampled at fixed directions of the texel's frame. Texels of one
//!   material that differ only in frame then differ in f_j too, but the training set is
//!   the same for every texel, so no interpolation scheme adds its own error, and the
//!   frame enters the fit per texel anyway (every sample is evaluated in the frame of
//!   the texel it hits).
//! - w (Eq. 7) normalizes: the mean norm of w·f_j equals the mean norm of [n_j, t_j], so
//!   reflectance and geometry weigh alike whatever the radiance scale.

use fabric_runtime::image::Image;
use glam::Vec3;

/// Dimension of the geometric part [n, t].
pub const GEOMETRY_DIMS: usize = 6;

/// The features of every texel (x fastest), row-major `texels × dim`, and w.
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    pub dim: usize,
    pub data: Vec<f32>,
    /// The weight w of Eq. 7 applied to f_j.
    pub weight: f32,
}

/// Builds the features from the texel frames and the training images (texel order).
pub fn texel_features(normals: &[Vec3], tangents: &[Vec3], images: &[Image]) -> Features {
    let texels = normals.len();
    let dim = GEOMETRY_DIMS + 3 * images.len();
    let mut data = vec![0.0f32; texels * dim];
    let (mut geo_norm, mut f_norm) = (0.0f64, 0.0f64);
    for j in 0..texels {
        let (n, t) = (normals[j], tangents[j]);
        let txy = (t.x * t.x + t.y * t.y).sqrt();
        let g = [n.x, n.y, n.z, t.x * t.x - t.y * t.y, 2.0 * t.x * t.y, 2.0 * t.z.abs() * txy];
        let row = &mut data[j * dim..(j + 1) * dim];
        row[..GEOMETRY_DIMS].copy_from_slice(&g);
        geo_norm += g.iter().map(|v| (v * v) as f64).sum::<f64>().sqrt();
        let mut f2 = 0.0f64;
        for (c, image) in images.iter().enumerate() {
            let v = image.pixels[j];
            row[GEOMETRY_DIMS + 3 * c..GEOMETRY_DIMS + 3 * c + 3].copy_from_slice(&v.to_array());
            f2 += v.as_dvec3().length_squared();
        }
        f_norm += f2.sqrt();
    }
    // Eq. 7: mean ‖w f‖ = mean ‖[n, t]‖; w = 1 when there is no radiance at all.
    let weight = if f_norm > 0.0 { (geo_norm / f_norm) as f32 } else { 1.0 };
    for row in data.chunks_mut(dim) {
        for v in &mut row[GEOMETRY_DIMS..] {
            *v *= weight;
        }
    }
    Features { dim, data, weight }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opposite_tangents_share_features_and_w_balances_the_parts() {
        let normals = vec![Vec3::Z; 2];
        let t = Vec3::new(0.8, 0.6, 0.0);
        let mut image = Image::new(2, 1);
        image.pixels = vec![Vec3::splat(100.0), Vec3::splat(100.0)];
        let f = texel_features(&normals, &[t, -t], &[image]);
        assert_eq!(f.data[..f.dim], f.data[f.dim..]);
        let fpart: f32 = f.data[GEOMETRY_DIMS..f.dim].iter().map(|v| v * v).sum::<f32>().sqrt();
        let gpart: f32 = f.data[..GEOMETRY_DIMS].iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((fpart - gpart).abs() < 1e-4 * gpart, "{fpart} vs {gpart}");
    }
}
