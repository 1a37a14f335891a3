//! The model side of a measurement: what the baker fits and validates with.
//!
//! The reference's measurement mode (the baker's `MeasureScene`) traces, for texel j and
//! a pair (ω_i, ω_o), rays through jittered points of the texel's surface towards −ω_o,
//! started on the slab's top plane of the periodic sheet. This module traces *the same
//! rays* through the model (the caller passes them; the periodic tile repeats as the
//! sheet does) and says what the model shows along each: which texel of the height field
//! it hits, whether the light sees that point (height-field shadowing), and which flyaway
//! nodes it crosses with what weight. At oblique views the ray to texel j crosses its
//! neighbours' relief first, so a training sample belongs to the texel the model
//! actually shows, not to j.
//!
//! [`measure_image`] is the model's twin of the reference's `render_image`: the mean
//! model radiance over given rays per texel, in texel order, comparable pixel for pixel.

use glam::Vec3;
use rayon::prelude::*;

use super::flyaways::visit_flyaways;
use super::heightfield::HfTrace;
use super::render::Scene;
use super::{CpuRenderError, CpuRenderOptions};
use crate::hybrid::HybridModel;
use crate::image::Image;
use crate::scene::{Light, Ray};

/// Where a probe ray meets the height field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Level-ℓ texel (i, j) of the hit (wrapped into the tile).
    pub texel: (u32, u32),
    /// World hit point.
    pub point: Vec3,
    /// Visibility of the scene's first light from the hit (1 without shadowing): the
    /// height field's, times what the flyaways let through toward it where they shadow
    /// the surface (`Scene::flyaway_shadow`).
    pub visibility: f32,
    /// Transmittance of the flyaways in front of the hit (1 when none were crossed or
    /// they were not marched).
    pub transmittance: f32,
}

/// A flyaway node crossed by a probe ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyawayHit {
    /// The node's flyaway BRDF index (`FlyawayNode::param`).
    pub param: u32,
    /// Fiber axis of the node.
    pub fiber: Vec3,
    /// World point where the ray enters the node.
    pub point: Vec3,
    /// Weight of the node's radiance in the pixel: transmittance in front × opacity.
    pub weight: f32,
    /// Visibility of the first light from the entry point.
    pub visibility: f32,
}

/// What one probe ray meets.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProbeTrace {
    pub surface: Option<SurfaceHit>,
    pub flyaways: Vec<FlyawayHit>,
}

impl Scene<'_> {
    /// Traces `ray` through level `level` of the model: the surface hit and, with
    /// `flyaways`, the flyaway nodes in front of it (and their shadow on it), each with
    /// the visibility of the scene's first light (or 1 with no light). The same march as [`Scene::trace_ray`].
    pub fn probe_ray(&self, ray: &Ray, level: usize, flyaways: bool) -> ProbeTrace {
        let mut out = ProbeTrace::default();
        let Some(t_top) = self.enter_top(ray) else {
            return out;
        };
        let mut steps = 0;
        let hit = self.tracer.trace(ray, t_top, f32::MAX, 0.0, self.options.max_steps, &mut steps);
        let t_end = match hit {
            HfTrace::Hit(t) => t,
            _ => t_top + self.model.tile.height_scale / -ray.d.z,
        };
        let mut limited = 0u32;
        let visibility = |p: Vec3, limited: &mut u32| self.lights.first().map_or(1.0, |l| self.visibility(p, &l.sample(p), limited));
        let mut transmittance = 1.0;
        if flyaways && let Some(f) = self.model.levels[level].flyaways.as_ref().filter(|f| !f.nodes.is_empty()) {
            let march = visit_flyaways(f, &self.grids[level], ray, t_top, t_end, self.options.max_flyaway_columns, |_, node, t_in, weight| {
                let point = ray.at(t_in);
                out.flyaways.push(FlyawayHit { param: node.param, fiber: node.tangent(), point, weight, visibility: visibility(point, &mut limited) });
            });
            transmittance = march.transmittance;
        }
        if let HfTrace::Hit(t) = hit {
            let point = ray.at(t);
            let v = visibility(point, &mut limited);
            let fly = match self.lights.first() {
                Some(l) if v > 0.0 && flyaways => {
                    let s = l.sample(point);
                    self.flyaway_shadow(level, point, s.wi, s.distance).0
                }
                _ => 1.0,
            };
            out.surface = Some(SurfaceHit { texel: self.texel_at(point, level), point, visibility: v * fly, transmittance });
        }
        out
    }
}

/// The model's measurement image for the pair (ω_i, ω_o) (`wi` toward a unit-irradiance
/// directional light): pixel (x, y) is the mean radiance of the model along the rays
/// `ray(x, y, s)`, s = 0..`rays_per_texel`, on the periodic tile at `level` — the twin of
/// the reference's `MeasureScene::render_image` when given its rays.
pub fn measure_image(model: &HybridModel, options: &CpuRenderOptions, wi: Vec3, level: usize, rays_per_texel: u32, ray: &(dyn Fn(u32, u32, u32) -> Ray + Sync)) -> Result<Image, CpuRenderError> {
    if rays_per_texel == 0 {
        return Err(CpuRenderError::Options("measure_image needs at least one ray per texel".into()));
    }
    if level >= model.levels.len() {
        return Err(CpuRenderError::Level { level: level as u32, count: model.levels.len() });
    }
    let lights = [Light::directional(wi, Vec3::ONE)];
    let scene = Scene::for_rays(model, &lights, CpuRenderOptions { periodic: true, ..options.clone() })?;
    let (w, h) = (model.width(), model.height_px());
    let rows: Vec<Vec<Vec3>> = (0..h)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| {
                    let mut sum = Vec3::ZERO;
                    for s in 0..rays_per_texel {
                        sum += scene.trace_ray(&ray(x, y, s), level).radiance;
                    }
                    sum / rays_per_texel as f32
                })
                .collect()
        })
        .collect();
    let image = Image { width: w, height: h, pixels: rows.concat() };
    if let Some((x, y, value)) = image.first_non_finite() {
        return Err(CpuRenderError::NonFinite { x, y, value });
    }
    Ok(image)
}
