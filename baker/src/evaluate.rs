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

use std::time::Instant;

use fabric_runtime::cpu::{CpuRenderOptions, render};
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::image::Image;
use fabric_runtime::scene::{Camera, Light, Projection};
use glam::Vec3;
use serde::Serialize;

use crate::bake::{BakeError, block_mean};
use crate::fit::directions::Pair;
use crate::fit::samples::half_seeds;
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
    /// The reference's own relative error at the block level (from its two halves).
    pub reference_noise: f64,
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

/// Renders the view with both renderers and measures the model's error.
#[allow(clippy::too_many_arguments)] // one view's full description
pub fn evaluate_view(volume: &FabricVolume, medium: &TracedMedium, model: &HybridModel, pair: &Pair, kind: ViewKind, pixels: u32, spp: u32, seed: u64) -> Result<(ViewError, ViewImages), BakeError> {
    let (camera, light) = view(volume, pair, kind, pixels);
    let t = Instant::now();
    let [sa, sb] = half_seeds(seed);
    let half = |s| crate::reference::render(medium, &camera, &(&light).into(), &RenderSettings { spp: (spp / 2).max(1), seed: s, ..Default::default() }, None).map(|(i, _)| i);
    let (a, b) = (half(sa)?, half(sb)?);
    let mut reference = Image::new(a.width, a.height);
    for (k, p) in reference.pixels.iter_mut().enumerate() {
        *p = 0.5 * (a.pixels[k] + b.pixels[k]);
    }
    let reference_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let options = CpuRenderOptions { periodic: true, supersampling: 4, ..Default::default() };
    let model_image = render(model, &camera, &[light], &options).map_err(|e| BakeError::Cluster(format!("model render: {e}")))?;
    let model_seconds = t.elapsed().as_secs_f64();
    let (pixel_error, block_error) = relative_errors(&model_image, &reference);
    let (ba, bb) = (block_mean(&a, 4), block_mean(&b, 4));
    let (_, noise) = relative_errors(&ba, &bb);
    let mean_ratio = model_image.mean() / reference.mean().max(1e-30);
    let (block16_error, _) = relative_errors(&block_mean(&model_image, 16), &block_mean(&reference, 16));
    let e = ViewError { pair: *pair, kind, pixel_error, block_error, block16_error, mean_ratio, reference_noise: 0.5 * noise, reference_seconds, model_seconds };
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
