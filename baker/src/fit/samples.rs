//! Training renderings and the samples the fit matches (paper §5.3.1–§5.3.2).
//!
//! A training rendering is the reference's measurement image of every texel for one
//! pair (ω_i, ω_o) ([`MeasureScene::render_image`]), rendered as two independent halves
//! so that its own noise is known. A **sample** is one of the rays behind a pixel, traced
//! through the model by the runtime's probe (`cpu::probe`): it records which texel the
//! model shows along that ray, that texel's frame, the light's visibility there, and the
//! angles the BRDF needs, so a cluster's fit evaluates exactly what the renderer will
//! show for that pixel. The geometric factors depend only on the frame, never on the
//! BRDF parameters, so they are computed once ([`Geo`]).

use std::time::Instant;

use fabric_runtime::brdf::{ClothFrame, DiffuseLaw, FiberLobes, cloth_angles, cloth_diffuse_cosine, cloth_fresnel_cos, cloth_half_cos};
use fabric_runtime::cpu::shading::volume_factor;
use fabric_runtime::cpu::{CpuRenderOptions, Scene, ShadowMode};
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::image::Image;
use fabric_runtime::scene::{Light, Ray};
use glam::Vec3;
use rayon::prelude::*;

use super::directions::Pair;
use crate::reference::rng::{Rng, mix64};
use crate::reference::{MeasureScene, ReferenceError};

/// The training renderings of the m configurations.
#[derive(Clone, Debug)]
pub struct TrainingImages {
    pub pairs: Vec<Pair>,
    /// Mean of the two halves per pair, texel order.
    pub images: Vec<Image>,
    /// The renders' own error: the relative RMSE of the mean estimated from the halves,
    /// ‖A − B‖ / (2‖(A + B)/2‖) over all pairs (the floor no fit can go below).
    pub noise: f64,
    pub spp: u32,
    pub seed: u64,
    pub paths: u64,
    pub seconds: f64,
}

impl TrainingImages {
    /// The weight of each pair's samples in the fit: s_p = R / R_p, R_p the RMS of pair
    /// p's image and R that over all pairs, so that the fit's Σ_p s_p² ‖L − L_ref‖²
    /// counts each pair's error relative to its own brightness, as the held-out figure
    /// (a relative RMSE per view, averaged over views) does; unweighted, the dim
    /// off-specular pairs hardly count beside the bright mirror ones. 1 where a pair's
    /// image is black. Measured (FIT_MEASUREMENTS.md): it helps silk (14 points) and satin
    /// (1) and costs twill, plain and felt 0.5–1.7; on by default (`fabric bake
    /// --unweighted-pairs` turns it off).
    pub fn pair_weights(&self) -> Vec<f32> {
        let rms: Vec<f64> = self.images.iter().map(|im| (im.pixels.iter().map(|p| p.as_dvec3().length_squared()).sum::<f64>() / im.pixels.len().max(1) as f64).sqrt()).collect();
        let all = (rms.iter().map(|r| r * r).sum::<f64>() / rms.len().max(1) as f64).sqrt();
        rms.iter().map(|&r| if r > 0.0 && all.is_finite() { (all / r) as f32 } else { 1.0 }).collect()
    }
}

/// Seeds of the two halves of a training render.
pub fn half_seeds(seed: u64) -> [u64; 2] {
    [mix64(seed ^ 0x6861_6c66_0001), mix64(seed ^ 0x6861_6c66_0002)]
}

/// Renders the training images: each pair as two halves of ⌈spp/2⌉ and ⌊spp/2⌋ samples.
pub fn render_training(scene: &MeasureScene, pairs: &[Pair], spp: u32, seed: u64, advance: &(dyn Fn() + Sync)) -> Result<TrainingImages, ReferenceError> {
    if spp < 2 {
        return Err(ReferenceError::ZeroSamples);
    }
    let start = Instant::now();
    let [sa, sb] = half_seeds(seed);
    let (na, nb) = (spp.div_ceil(2), spp / 2);
    let (mut images, mut paths, mut diff2, mut mean2) = (Vec::with_capacity(pairs.len()), 0u64, 0f64, 0f64);
    for p in pairs {
        let (a, st_a) = scene.render_image(p.wi, p.wo, na, sa)?;
        let (b, st_b) = scene.render_image(p.wi, p.wo, nb, sb)?;
        paths += st_a.paths + st_b.paths;
        let (wa, wb) = (na as f32 / spp as f32, nb as f32 / spp as f32);
        let mut mean = Image::new(a.width, a.height);
        for (k, m) in mean.pixels.iter_mut().enumerate() {
            *m = wa * a.pixels[k] + wb * b.pixels[k];
            diff2 += (a.pixels[k] - b.pixels[k]).as_dvec3().length_squared();
            mean2 += m.as_dvec3().length_squared();
        }
        images.push(mean);
        advance();
    }
    let noise = if mean2 > 0.0 { 0.5 * (diff2 / mean2).sqrt() } else { 0.0 };
    Ok(TrainingImages { pairs: pairs.to_vec(), images, noise, spp, seed, paths, seconds: start.elapsed().as_secs_f64() })
}

/// The BRDF-independent factors of one sample in the frame of the texel it hits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Geo {
    /// θ_i + θ_o and φ_i + φ_o (Eq. 2–3).
    pub theta_sum: f32,
    pub phi_sum: f32,
    /// cos φ_i, for the shadowing term.
    pub cos_phi_i: f32,
    /// cos θ_d, for the Fresnel term.
    pub cos_d: f32,
    /// max(n·ω_i, 0) · visibility: the factor every lobe carries.
    pub cos_i: f32,
    /// The diffuse term's factor: `cloth_diffuse_cosine` of the diffuse law · visibility
    /// (= `cos_i` for Lambert's; only lobe 0's frame's is used).
    pub kd_cos: f32,
}

impl Geo {
    /// The factors for directions `wi`, `wo` in `frame`, with the light's `visibility`,
    /// the diffuse term by `diffuse` (the model's law; Lambert's for a flyaway).
    pub fn new(frame: &ClothFrame, wi: Vec3, wo: Vec3, visibility: f32, diffuse: DiffuseLaw) -> Geo {
        let (ai, ao) = (cloth_angles(frame, wi), cloth_angles(frame, wo));
        let kd_cos = cloth_diffuse_cosine(diffuse, frame.n, wi, wo) * visibility;
        Geo { theta_sum: ai.theta + ao.theta, phi_sum: ai.phi + ao.phi, cos_phi_i: ai.cos_phi, cos_d: cloth_fresnel_cos(&ai, &ao), cos_i: frame.n.dot(wi).max(0.0) * visibility, kd_cos }
    }

    /// The factors of a flyaway fibre in its frame `frame` (the fibre frame seen from
    /// `wo`) under the model's law `lobes`: Lambert's diffuse term on the side facing the
    /// viewer, and for [`FiberLobes::Cylinder`] the lobes of `brdf::cloth_cylinder_lobe`
    /// (φ_i + φ_o = 0, shadowing and cosine at the half-angle c = cos(φ_i / 2)).
    pub fn fiber(frame: &ClothFrame, wi: Vec3, wo: Vec3, visibility: f32, lobes: FiberLobes) -> Geo {
        let g = Geo::new(frame, wi, wo, visibility, DiffuseLaw::Lambert);
        match lobes {
            FiberLobes::Facing => g,
            FiberLobes::Cylinder => {
                let ai = cloth_angles(frame, wi);
                let c = cloth_half_cos(ai.cos_phi);
                Geo { phi_sum: 0.0, cos_phi_i: c, cos_i: ai.cos_theta * c * visibility, ..g }
            }
        }
    }

    /// The factors with every term weighted by `w` (a sample's weight in the fit).
    pub fn weighted(self, w: f32) -> Geo {
        Geo { cos_i: self.cos_i * w, kd_cos: self.kd_cos * w, ..self }
    }
}

/// One probe ray of one pixel (or of one dense measurement). A pixel of the model is
/// the mean of its rays' radiance; the fit matches each ray to the pixel's value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Level-0 texel the model shows along the ray (index i + w·j).
    pub hit: u32,
    /// Which target: the training pixel (pair · texels + pixel), or a dense value.
    pub target: u32,
    /// The pair, as the caller numbers its directions (so `geo` can be recomputed in
    /// another frame), and the light's visibility times the ray's weight.
    pub dirs: u32,
    pub vis: f32,
    pub geo: Geo,
}

/// How the samples are traced through the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeOptions {
    /// Rays per pixel (the first of the reference's own jitters).
    pub rays: u32,
    /// Height-field shadowing of the light in the model.
    pub shadows: bool,
    /// The model's volumetric factor on surface hits (`cpu::shading::volume_factor`).
    pub volumetric: bool,
    /// The model's diffuse law (`brdf::cloth_diffuse_cosine`).
    pub diffuse: DiffuseLaw,
}

/// Probes the rays of `texels` for the pair (`wi`, `wo`): ray s of texel (x, y) is the
/// reference's sample s of seed `jitter_seed` (the jitter `Rng::new(seed, texel, s)`
/// draws first), through the model `model` (its height field and texel frames).
/// Returns samples whose target is `target(texel index)` and whose pair is `dirs`. Rays
/// that miss the surface (none should on a periodic tile) are dropped.
#[allow(clippy::too_many_arguments)] // the rays' full description: model, sheet, pair, texels, jitter, targets
pub fn probe_samples(model: &HybridModel, measure: &MeasureScene, (wi, wo, dirs): (Vec3, Vec3, u32), texels: &[u32], options: &ProbeOptions, jitter: &(dyn Fn(u32, u32) -> (f32, f32) + Sync), target: &(dyn Fn(u32) -> u32 + Sync)) -> Vec<Sample> {
    let lights = [Light::directional(wi, Vec3::ONE)];
    let factor = if options.volumetric { volume_factor(wi, wo) } else { 1.0 };
    let render = CpuRenderOptions { periodic: true, shadows: if options.shadows { ShadowMode::On } else { ShadowMode::Off }, ..Default::default() };
    let Ok(scene) = Scene::for_rays(model, &lights, render) else {
        return Vec::new();
    };
    let (w, _) = measure.texels();
    let frames: Vec<ClothFrame> = match &model.levels[0].surface {
        fabric_runtime::hybrid::Surface::Clustered { texels, .. } => texels.iter().map(|t| t.frame()).collect(),
        _ => return Vec::new(),
    };
    texels
        .par_iter()
        .flat_map_iter(|&texel| {
            let (x, y) = ((texel as usize % w), (texel as usize / w));
            let scene = &scene;
            let frames = &frames;
            (0..options.rays).filter_map(move |s| {
                let (u, v) = jitter(texel, s);
                let (o, d) = measure.sample_ray(x, y, u, v, wo);
                let probe = scene.probe_ray(&Ray::new(o, d), 0, false);
                let hit = probe.surface?;
                let index = hit.texel.0 + model.width() * hit.texel.1;
                let vis = hit.visibility * factor;
                Some(Sample { hit: index, target: target(texel), dirs, vis, geo: Geo::new(&frames[index as usize], wi, wo, vis, options.diffuse) })
            })
        })
        .collect()
}

/// The jitter of sample `s` of texel `texel` in `render_image(.., seed)`.
pub fn image_jitter(seed: u64) -> impl Fn(u32, u32) -> (f32, f32) + Sync {
    move |texel, s| Rng::new(seed, texel as u64, s as u64).next_2d()
}

/// The jitter of sample `s` of pair `pair` in `measure_texel(texel, .., seed)`.
pub fn texel_jitter(seed: u64, texel: u32, pair: u32, s: u32) -> (f32, f32) {
    let key = mix64(seed ^ mix64(texel as u64));
    Rng::new(key, pair as u64, s as u64).next_2d()
}

/// Indices 0..n grouped by `key(i)` < `groups`, each group in increasing order (a
/// stable counting sort): group g is `order[starts[g]..starts[g + 1]]`. Four bytes a
/// sample where a vector of targets per texel or cluster, built all at once, held every
/// sample's factors a second time (the 512² bake's peak memory).
pub struct Groups {
    pub starts: Vec<usize>,
    pub order: Vec<u32>,
}

impl Groups {
    pub fn by_key(n: usize, groups: usize, key: impl Fn(usize) -> usize) -> Groups {
        // Indices are stored in 4 bytes: 2³² samples would be ~100 GB of samples first.
        assert!(u32::try_from(n).is_ok(), "{n} samples exceed the 2^32 a group index holds");
        let mut starts = vec![0usize; groups + 1];
        for i in 0..n {
            starts[key(i) + 1] += 1;
        }
        for g in 0..groups {
            starts[g + 1] += starts[g];
        }
        let mut next = starts.clone();
        let mut order = vec![0u32; n];
        for i in 0..n {
            let g = key(i);
            order[next[g]] = i as u32;
            next[g] += 1;
        }
        Groups { starts, order }
    }

    /// The indices in group `g`.
    pub fn group(&self, g: usize) -> &[u32] {
        &self.order[self.starts[g]..self.starts[g + 1]]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn groups_hold_every_index_once_in_order() {
        let keys = [2usize, 0, 2, 1, 0, 2, 3, 0];
        let g = super::Groups::by_key(keys.len(), 5, |i| keys[i]);
        assert_eq!(g.group(0), &[1, 4, 7]);
        assert_eq!(g.group(1), &[3]);
        assert_eq!(g.group(2), &[0, 2, 5]);
        assert_eq!(g.group(3), &[6]);
        assert!(g.group(4).is_empty());
        assert_eq!(g.order.len(), keys.len());
    }

    use super::*;

    fn flat(value: f32) -> Image {
        let mut im = Image::new(4, 4);
        im.pixels.iter_mut().for_each(|p| *p = Vec3::splat(value));
        im
    }

    fn images(values: &[f32]) -> TrainingImages {
        TrainingImages { pairs: Vec::new(), images: values.iter().map(|&v| flat(v)).collect(), noise: 0.0, spp: 2, seed: 1, paths: 0, seconds: 0.0 }
    }

    #[test]
    fn pair_weights_make_each_pair_count_relative_to_its_brightness() {
        let w = images(&[0.1, 0.4, 0.0]).pair_weights();
        // Weighted, each pair's image has the same RMS: s_p · R_p is one value.
        assert!((w[0] * 0.1 - w[1] * 0.4).abs() < 1e-6, "{w:?}");
        assert!((w[0] / w[1] - 4.0).abs() < 1e-5, "{w:?}");
        // A black image keeps weight 1 (nothing to be relative to), and adds nothing.
        assert_eq!(w[2], 1.0);
        // Equal images weigh 1 each: the weights are scaled to the set's own RMS.
        assert!(images(&[0.3, 0.3]).pair_weights().iter().all(|v| (v - 1.0).abs() < 1e-6));
    }
}
