//! Shading a hit (the CPU twin of `shading.glsl`): the texel's lobes, or a flyaway's in
//! its fiber frame, under each light, with optional height-field shadowing.
//!
//! Radiance toward ω_o (runtime/HYBRID_FORMAT.md §6):
//!
//! ```text
//! L_o = Σ_lights E · V · [ k_d · D(n_0, ω_i, ω_o) + Σ_j cloth_lobe_j(ω_i, ω_o) · max(n_j·ω_i, 0) ]
//! ```
//!
//! E the light's irradiance perpendicular to its beam at the point, V its visibility
//! (1 without shadowing), lobe j in its own frame (n_j, t_j); lobe 0's frame carries
//! the diffuse term, whose cosine factor D is the model's diffuse law
//! ([`cloth_diffuse_cosine`]: Lambert's max(n_0·ω_i, 0), or Lommel–Seeliger's; flyaways
//! always Lambert's). With one shared frame this is E·V·f_r·max(n·ω_i, 0), f_r of Eq. 1:
//! exactly what the fit matches (DESIGN.md §5, "fit radiance, not ratios").
//!
//! A light below the tile plane (ω_i.z < 0) reaches the viewer only through the cloth:
//! its contribution is E · f_t · |ω_i.z|, the texel's transmission term in lobe 0's frame
//! ([`texel_transmission_response`]), with no height-field visibility (the light crosses
//! the sheet; the term carries its attenuation) and nothing reflected. A texel without a
//! transmission term (a BRDF-only model) passes nothing.

use glam::Vec3;

use crate::brdf::{BrdfReading, DiffuseLaw, FiberLobes, K_MAX, cloth_cylinder_lobe, cloth_diffuse_cosine, cloth_fiber_frame, cloth_lobe, cloth_transmission_response, cloth_visibility};
use crate::hybrid::TexelBrdf;
use crate::scene::{Light, LightSample};

/// Reflected radiance toward `wo` per unit irradiance from `wi` (both unit, pointing
/// away from the surface), the diffuse term by `diffuse` (the model's law at surface
/// hits, [`DiffuseLaw::Lambert`] at flyaways), the lobes by the cylinder law where
/// `b.cylinder` (a flyaway of a model with [`FiberLobes::Cylinder`]).
#[inline]
pub fn texel_response(b: &TexelBrdf, wi: Vec3, wo: Vec3, reading: BrdfReading, diffuse: DiffuseLaw) -> Vec3 {
    let p = &b.params;
    let kd = p.kd.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    let mut r = kd * cloth_diffuse_cosine(diffuse, b.frames[0].n, wi, wo);
    for (lobe, frame) in p.lobes().iter().zip(&b.frames) {
        if b.cylinder {
            r += cloth_cylinder_lobe(lobe, p.eta, p.a, frame, wi, wo, reading);
            continue;
        }
        let cos_i = frame.n.dot(wi);
        if cos_i > 0.0 {
            r += cloth_lobe(lobe, p.eta, p.a, frame, wi, wo, reading) * cos_i;
        }
    }
    r * cloth_visibility(b.gradient, b.curvature, wi, wo)
}

/// Transmitted radiance toward `wo` per unit irradiance from `wi` on the other side of
/// the tile plane (zero for a texel without a transmission term, or on the same side).
#[inline]
pub fn texel_transmission_response(b: &TexelBrdf, wi: Vec3, wo: Vec3) -> Vec3 {
    cloth_transmission_response(&b.transmission, &b.frames[0], wi, wo)
}

/// Smallest μ_i + μ_o of the volumetric factor (caps it at 20).
pub const VOLUME_MU_MIN: f32 = 0.1;

/// The volumetric factor of a surface hit in a model baked with it
/// (runtime/HYBRID_FORMAT.md §6): 2 / (μ_i + μ_o), μ = ω·ẑ the cosines to the tile's
/// normal. The single scattering of a semi-infinite medium goes as μ_i / (μ_i + μ_o)
/// rather than Lambert's μ_i (Lommel–Seeliger), so a fabric's mirror response grows
/// towards grazing angles where a surface BRDF's falls; the factor is 1 at normal
/// incidence and view.
#[inline]
pub fn volume_factor(wi: Vec3, wo: Vec3) -> f32 {
    2.0 / (wi.z.max(0.0) + wo.z.max(0.0)).max(VOLUME_MU_MIN)
}

/// Replaces every frame of a flyaway BRDF by the fiber frame of axis `fiber` seen from
/// `wo` (DESIGN.md §5), its lobes by the model's law `lobes`.
#[inline]
pub fn in_fiber_frame(mut b: TexelBrdf, fiber: Vec3, wo: Vec3, lobes: FiberLobes) -> TexelBrdf {
    b.frames = [cloth_fiber_frame(fiber, wo); crate::brdf::MAX_LOBES];
    b.cylinder = lobes == FiberLobes::Cylinder;
    b
}

/// Radiance leaving point `p` toward `wo` under `lights`; `visible(p, sample)` is the
/// light's visibility in [0, 1] (shadowing).
pub fn shade(b: &TexelBrdf, p: Vec3, wo: Vec3, lights: &[Light], reading: BrdfReading, diffuse: DiffuseLaw, mut visible: impl FnMut(Vec3, &LightSample) -> f32) -> Vec3 {
    let mut radiance = Vec3::ZERO;
    for light in lights {
        let s = light.sample(p);
        if s.irradiance.max_element() <= 0.0 {
            continue;
        }
        if s.wi.z < 0.0 {
            radiance += s.irradiance * texel_transmission_response(b, s.wi, wo);
            continue;
        }
        let response = texel_response(b, s.wi, wo, reading, diffuse);
        if response.max_element() <= 0.0 {
            continue;
        }
        radiance += s.irradiance * response * visible(p, &s);
    }
    radiance
}

/// [`shade`] for a blend of texels (the bilinear filter of a coarse level): Σ_lights
/// E · V · Σ_k w_k · response_k, each light's visibility evaluated once.
pub fn shade_blend(texels: &[(TexelBrdf, f32)], p: Vec3, wo: Vec3, lights: &[Light], reading: BrdfReading, diffuse: DiffuseLaw, mut visible: impl FnMut(Vec3, &LightSample) -> f32) -> Vec3 {
    let mut radiance = Vec3::ZERO;
    for light in lights {
        let s = light.sample(p);
        if s.irradiance.max_element() <= 0.0 {
            continue;
        }
        if s.wi.z < 0.0 {
            radiance += s.irradiance * texels.iter().map(|(b, w)| *w * texel_transmission_response(b, s.wi, wo)).sum::<Vec3>();
            continue;
        }
        let response: Vec3 = texels.iter().map(|(b, w)| *w * texel_response(b, s.wi, wo, reading, diffuse)).sum();
        if response.max_element() <= 0.0 {
            continue;
        }
        radiance += s.irradiance * response * visible(p, &s);
    }
    radiance
}
