//! Held-out accuracy of a baked model: the CPU renderer of the model against the
//! reference path tracer of the volume, same camera and light, at view/light pairs the
//! fit never saw (`fit::directions::held_out_pairs`).
//!
//! Each view is the periodic sheet (both renderers repeat the tile) seen by an
//! orthographic camera aimed at the tile's top centre from ω_o, one pixel per texel
//! across, lit by a unit directional light from ω_i; or, for [`ViewKind::Perspective`],
//! a pinhole camera over the sheet lit by a point light. The figure is the relative
//! RMSE ‖A − B‖₂/‖B‖₂ over linear RGB, per pixel and over 4×4-pixel blocks (a footprint
//! of about 4×4 texels: the model is not meant to place each fiber where the volume has
//! it). The reference is rendered as two halves; their difference bounds its own noise.
//!
//! A figure over 4×4 blocks needs a scale: the truth itself changes fast with angle at
//! that footprint (10% for a turn of both directions by 3–4°,
//! `baker/studies/angular_sharpness/`). So each view can also measure a yardstick: the
//! reference again with its light turned a few degrees, against itself.

use std::time::Instant;

use fabric_runtime::cpu::{CpuRenderOptions, render};
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::image::Image;
use fabric_runtime::scene::{Camera, Light, Projection};
use glam::{Quat, Vec3};
use serde::Serialize;

use crate::bake::{BakeError, block_mean};
use crate::fit::directions::Pair;
use crate::fit::samples::half_seeds;
use crate::reference::rng::mix64;
use crate::reference::{Lookup, MediumOptions, RenderSettings, TracedMedium};
use crate::volume::FabricVolume;

/// How a held-out view looks at the sheet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewKind {
    /// Orthographic camera from ω_o, directional light from ω_i.
    Orthographic,
    /// Pinhole camera from ω_o at 1.5 tile widths, point light from ω_i at 2 tile widths
    /// (irradiance 1 at the tile centre).
    Perspective,
}

/// One held-out view and its errors.
#[derive(Clone, Debug, Serialize)]
pub struct ViewError {
    pub pair: Pair,
    pub kind: ViewKind,
    /// Relative RMSE per pixel and over 4×4 blocks.
    pub pixel_error: f64,
    pub block_error: f64,
    /// Relative RMSE over 16×16 blocks (what remains when parallax and fiber
    /// placement are forgiven: the angular error).
    pub block16_error: f64,
    /// mean(model) / mean(reference): a global bias shows here.
    pub mean_ratio: f64,
    /// The reference's own relative error over 4×4 blocks (from its two halves).
    pub reference_noise: f64,
    /// `block_error` net of the reference's noise, √(max(e² − noise², 0)) (the model's
    /// image is noise-free: e² = truth² + noise²); what a converged reference would
    /// read, as the yardstick is taken. Where the reference is noisy (backlit views at
    /// 64 spp: 10–26%) it is the figure to read the model by.
    pub block_error_net: f64,
    /// The yardstick: the reference lit from ω_i turned by [`ViewError::light_turn_deg`]
    /// (about a seeded random axis, same camera) against the reference, over 4×4 blocks,
    /// net of both renders' noise — how much the truth itself changes for a small error
    /// of angle, to read `block_error` against. `None` when not measured.
    pub light_turned_error: Option<f64>,
    pub light_turn_deg: f32,
    pub reference_seconds: f64,
    pub model_seconds: f64,
}

/// Images of one view (for pictures).
pub struct ViewImages {
    pub reference: Image,
    pub model: Image,
}

/// The camera and light of a held-out view of `volume`'s tile.
pub fn view(volume: &FabricVolume, pair: &Pair, kind: ViewKind, pixels: u32) -> (Camera, Light) {
    let bbox = volume.bbox();
    let size = bbox.size();
    let centre = Vec3::new(bbox.min.x + 0.5 * size.x, bbox.min.y + 0.5 * size.y, bbox.max.z);
    let width = size.x.max(size.y);
    let up = if pair.wo.z > 0.999 { Vec3::Y } else { Vec3::Z };
    match kind {
        ViewKind::Orthographic => {
            let h = ((pixels as f32) * size.y / size.x).round().max(1.0) as u32;
            let camera = Camera { origin: centre + 2.0 * width * pair.wo, target: centre, up, projection: Projection::Orthographic { extent: size.x }, width: pixels, height: h };
            (camera, Light::directional(pair.wi, Vec3::ONE))
        }
        ViewKind::Perspective => {
            let camera = Camera { origin: centre + 1.5 * width * pair.wo, target: centre, up, projection: Projection::Perspective { fov_x_deg: 30.0 }, width: pixels, height: pixels };
            let d = 2.0 * width;
            (camera, Light::Point { position: centre + d * pair.wi, intensity: Vec3::splat(d * d) })
        }
    }
}

/// `w` turned by `deg` degrees about an axis perpendicular to it, at an angle about `w`
/// drawn from `seed`; the turn is tried at other angles (and halved) until the result
/// stays `min_z` above the tile plane on `w`'s side, so a light does not cross it.
pub fn turned(w: Vec3, deg: f32, seed: u64, min_z: f32) -> Vec3 {
    let (a, b) = w.any_orthonormal_pair();
    let start = (mix64(seed) >> 40) as f32 / (1u64 << 24) as f32 * std::f32::consts::TAU;
    let mut deg = deg;
    for _ in 0..4 {
        for k in 0..8 {
            let p = start + k as f32 * std::f32::consts::FRAC_PI_4;
            let axis = a * p.cos() + b * p.sin();
            let v = (Quat::from_axis_angle(axis, deg.to_radians()) * w).normalize();
            if v.z * w.z.signum() >= min_z {
                return v;
            }
        }
        deg *= 0.5;
    }
    w
}

/// The two halves of the reference of one view and their mean.
fn reference_halves(medium: &TracedMedium, camera: &Camera, light: &Light, spp: u32, seed: u64) -> Result<[Image; 3], BakeError> {
    let [sa, sb] = half_seeds(seed);
    let half = |s| crate::reference::render(medium, camera, &light.into(), &RenderSettings { spp: (spp / 2).max(1), seed: s, ..Default::default() }, None).map(|(i, _)| i);
    let (a, b) = (half(sa)?, half(sb)?);
    let mut mean = Image::new(a.width, a.height);
    for (k, p) in mean.pixels.iter_mut().enumerate() {
        *p = 0.5 * (a.pixels[k] + b.pixels[k]);
    }
    Ok([a, b, mean])
}

/// The relative error over 4×4 blocks of the mean of two halves, from their difference.
fn half_noise(a: &Image, b: &Image) -> f64 {
    0.5 * relative_errors(a, b).1
}

/// Renders the view with both renderers and measures the model's error; with
/// `light_turn_deg` > 0 also the yardstick [`ViewError::light_turned_error`] (one more
/// reference).
#[allow(clippy::too_many_arguments)] // one view's full description
pub fn evaluate_view(volume: &FabricVolume, medium: &TracedMedium, model: &HybridModel, pair: &Pair, kind: ViewKind, pixels: u32, spp: u32, seed: u64, light_turn_deg: f32) -> Result<(ViewError, ViewImages), BakeError> {
    let (camera, light) = view(volume, pair, kind, pixels);
    let t = Instant::now();
    let [a, b, reference] = reference_halves(medium, &camera, &light, spp, seed)?;
    let reference_seconds = t.elapsed().as_secs_f64();
    let light_turned_error = if light_turn_deg > 0.0 {
        let turned_pair = Pair { wi: turned(pair.wi, light_turn_deg, seed ^ 0x7475_726e, 0.05), ..*pair };
        let (_, turned_light) = view(volume, &turned_pair, kind, pixels);
        let [ta, tb, t_mean] = reference_halves(medium, &camera, &turned_light, spp, seed ^ 0x7475_726e)?;
        let (_, e) = relative_errors(&t_mean, &reference);
        // Net of both renders' noise (independent): e² = truth² + noise_a² + noise_b².
        let noise2 = half_noise(&a, &b).powi(2) + half_noise(&ta, &tb).powi(2);
        Some((e * e - noise2).max(0.0).sqrt())
    } else {
        None
    };
    let t = Instant::now();
    let options = CpuRenderOptions { periodic: true, supersampling: 4, ..Default::default() };
    let model_image = render(model, &camera, &[light], &options).map_err(|e| BakeError::Cluster(format!("model render: {e}")))?;
    let model_seconds = t.elapsed().as_secs_f64();
    let (pixel_error, block_error) = relative_errors(&model_image, &reference);
    let mean_ratio = model_image.mean() / reference.mean().max(1e-30);
    let (block16_error, _) = relative_errors(&block_mean(&model_image, 16), &block_mean(&reference, 16));
    let reference_noise = half_noise(&a, &b);
    let block_error_net = (block_error * block_error - reference_noise * reference_noise).max(0.0).sqrt();
    let e = ViewError { pair: *pair, kind, pixel_error, block_error, block16_error, mean_ratio, reference_noise, block_error_net, light_turned_error, light_turn_deg, reference_seconds, model_seconds };
    Ok((e, ViewImages { reference, model: model_image }))
}

/// (per-pixel, 4×4-block) relative RMSE of `test` against `reference`.
pub fn relative_errors(test: &Image, reference: &Image) -> (f64, f64) {
    let rel = |a: &Image, b: &Image| {
        let (mut d, mut r) = (0f64, 0f64);
        for (p, q) in a.pixels.iter().zip(&b.pixels) {
            d += (*p - *q).as_dvec3().length_squared();
            r += q.as_dvec3().length_squared();
        }
        if r > 0.0 { (d / r).sqrt() } else { 0.0 }
    };
    (rel(test, reference), rel(&block_mean(test, 4), &block_mean(reference, 4)))
}

/// The full (unmasked) periodic medium of `volume`, for held-out references.
pub fn reference_medium(volume: &FabricVolume, lookup: Lookup) -> Result<TracedMedium<'_>, BakeError> {
    Ok(TracedMedium::new(volume, MediumOptions { lookup, periodic: true, ..Default::default() })?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turned_direction_is_the_asked_angle_away_and_stays_above_the_plane() {
        for (k, w) in [Vec3::Z, Vec3::new(0.3, -0.2, 0.9).normalize(), Vec3::new(0.86, 0.0, 0.1).normalize()].into_iter().enumerate() {
            for deg in [2.5f32, 5.0, 10.0] {
                let v = turned(w, deg, k as u64 * 7 + 3, 0.05);
                assert!(v.z >= 0.05, "{w} turned {deg}° fell to {v}");
                let got = w.dot(v).clamp(-1.0, 1.0).acos().to_degrees();
                // A direction near the plane may have had its turn halved to stay above it.
                assert!((got - deg).abs() < 0.05 || (w.z < 0.2 && got > 0.0 && got < deg), "{w} turned {deg}°: {got}°");
                assert_eq!(v, turned(w, deg, k as u64 * 7 + 3, 0.05), "deterministic per seed");
            }
        }
        // Below the plane (a backlit light) it stays below.
        let w = Vec3::new(0.2, 0.1, -0.97).normalize();
        assert!(turned(w, 5.0, 1, 0.05).z <= -0.05);
    }
}
