//! The surface refitted behind the flyaways: samples of the whole model against the full
//! volume's training images.
//!
//! The surface is fitted first, through a model with no flyaways in it, on renderings of
//! the volume (`bake::SurfaceMask`: with V masked by default), then the flyaways on
//! renderings of the full volume with the surface fixed (paper §5.3.4). The surface's
//! fit never saw the flyaways in front of it: what they hide, and (with a mask) what the
//! mask removed that they do not hold. Refitting each texel behind them lowers the whole
//! model's error against the full volume's training images (64², over 4×4 blocks, with
//! V masked: silk 15.4 → 13.9%, satin 17.6 → 15.8%, felt 16.1 → 14.2%;
//! baker/FIT_MEASUREMENTS.md, "What the surface fit sees"). With the flyaways fixed a
//! pixel is linear in the surface's k_d, k_j again:
//!
//! ```text
//! L(ray) = F(ray) + T(ray) · V(ray) · f_t(ω_i, ω_o)
//! ```
//!
//! F the flyaways' radiance along the ray, T the flyaways' transmittance in front of the
//! surface hit, V the light's visibility there (through the flyaways where they shadow
//! the surface), f_t the texel's response. Each probe ray becomes a sample of texel t
//! whose target is the pixel less F and whose visibility carries T.
//!
//! A ray whose surface hit lies mostly hidden (T < [`MIN_TRANSMITTANCE`]) is left out:
//! its pixel is the flyaways' and says little of the surface, and a texel seen only
//! through them would otherwise buy any k (felt 128²: a k_d of hundreds, one white pixel
//! in a held-out view). A texel left with fewer than [`MIN_SAMPLES`] samples keeps what
//! the first refinement gave it.

/// The least transmittance in front of a surface hit for its ray to be a sample.
pub const MIN_TRANSMITTANCE: f32 = 0.5;

/// The fewest samples a texel is refitted from.
pub const MIN_SAMPLES: usize = 8;

use fabric_runtime::cpu::shading::volume_factor;
use fabric_runtime::cpu::{CpuRenderOptions, Scene, ShadowMode};
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::scene::{Light, Ray};
use glam::Vec3;
use rayon::prelude::*;

use super::samples::{Geo, Sample, TrainingImages, image_jitter};
use crate::reference::MeasureScene;

/// The samples of the whole model `model` along the rays of the training images
/// `training` (`rays` per pixel, jitter from `jitter_seed`), each with its target: the
/// training pixel less the flyaways' radiance along that ray, which `dark` (the same
/// model with every surface texel black) renders. A sample's `target` indexes the
/// pixel (pair · texels + pixel) and its `vis` carries the transmittance in front.
pub fn behind_samples(model: &HybridModel, dark: &HybridModel, measure: &MeasureScene, training: &TrainingImages, jitter_seed: u64, rays: u32, shadows: bool) -> Vec<(Sample, Vec3)> {
    let (w, h) = measure.texels();
    let texels = w * h;
    let jitter = image_jitter(jitter_seed);
    let render = CpuRenderOptions { periodic: true, shadows: if shadows { ShadowMode::On } else { ShadowMode::Off }, ..Default::default() };
    let mut out = Vec::new();
    for (c, pair) in training.pairs.iter().enumerate() {
        let lights = [Light::directional(pair.wi, Vec3::ONE)];
        let (Ok(scene), Ok(dark_scene)) = (Scene::for_rays(model, &lights, render.clone()), Scene::for_rays(dark, &lights, render.clone())) else {
            continue;
        };
        let factor = if model.meta.volumetric { volume_factor(pair.wi, pair.wo) } else { 1.0 };
        let image = &training.images[c];
        let batch: Vec<(Sample, Vec3)> = (0..texels)
            .into_par_iter()
            .flat_map_iter(|j| {
                let (x, y) = (j % w, j / w);
                let (scene, dark_scene, jitter) = (&scene, &dark_scene, &jitter);
                (0..rays).filter_map(move |s| {
                    let (u, v) = jitter(j as u32, s);
                    let (o, d) = measure.sample_ray(x, y, u, v, pair.wo);
                    let ray = Ray::new(o, d);
                    let hit = scene.probe_ray(&ray, 0, true).surface.filter(|h| h.transmittance >= MIN_TRANSMITTANCE)?;
                    let flyaways = dark_scene.trace_ray(&ray, 0).radiance;
                    let index = hit.texel.0 + model.width() * hit.texel.1;
                    let vis = hit.visibility * hit.transmittance * factor;
                    // The frame-dependent factors are recomputed in the texel's frames by the caller.
                    let sample = Sample { hit: index, target: (c * texels + j) as u32, dirs: c as u32, vis, geo: Geo::default() };
                    Some((sample, image.pixels[j] - flyaways))
                })
            })
            .collect();
        out.extend(batch);
    }
    out
}
