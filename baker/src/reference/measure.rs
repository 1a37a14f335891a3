//! Measurement mode: what the baker fits its BRDF to (docs/DESIGN.md §5,
//! "Measurement").
//!
//! For texel (x, y) and a pair (ω_i, ω_o): the radiance leaving the periodic sample
//! towards ω_o along the ray through the surface point
//!   s = (x + u, y + v, h(x, y))      (u, v) uniform over the texel (voxel units)
//! started outside the volume (above it when ω_o points up, below when it points down),
//! under a directional light from ω_i of unit irradiance perpendicular to the beam.
//! The value is radiance (no division by any cosine), so a fitted model is compared on
//! exactly what it will render. Everything in front of s along the ray (for example
//! flyaway fibers above the surface) is part of the measurement, as it is of a render.
//!
//! A texel is one voxel column: texel (x, y) spans [x, x+1) × [y, y+1) voxels. Height
//! maps are in world z, one value per texel, x fastest (`height[x + xres·y]`); without
//! one the surface is the volume's top plane. A voxel mask removes voxels (the baker
//! removes the flyaways when it measures the surface).
//!
//! Build a `MeasureScene` once per (volume, mask, height map) and call it as often as
//! needed: construction builds the masked density and its majorant grid; each call
//! is a pure function of its arguments and seed (bit-identical for any thread count).

use fabric_runtime::image::Image;
use fabric_runtime::scene::Light;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::ReferenceError;
use super::integrator::{Lighting, PathSettings, PathStats, radiance};
use super::medium::{Lookup, MediumOptions};
use super::rng::{Rng, mix64};
use super::tracking::TracedMedium;
use crate::volume::FabricVolume;

/// Samples of one (texel, pair) are summed in chunks of this many, in parallel.
const CHUNK: u32 = 64;

/// Smallest |ω_o.z| accepted: the ray must reach the surface from outside the slab.
const MIN_COS_VIEW: f32 = 1e-3;

/// The periodic sample, prepared for measurements.
pub struct MeasureScene<'v> {
    medium: TracedMedium<'v>,
    height: Option<Vec<f32>>,
    /// Path-length controls (default: full multiple scattering).
    pub path: PathSettings,
}

impl<'v> MeasureScene<'v> {
    /// `height_map`: world z per texel (x fastest), or `None` for the top plane.
    /// `mask`: voxels to remove (`true` = removed), volume order.
    pub fn new(volume: &'v FabricVolume, lookup: Lookup, height_map: Option<&[f32]>, mask: Option<&[bool]>) -> Result<MeasureScene<'v>, ReferenceError> {
        let [nx, ny, _] = volume.dims();
        if let Some(h) = height_map {
            if h.len() != nx * ny {
                return Err(ReferenceError::HeightMapLength { expected: nx * ny, got: h.len() });
            }
            if let Some(i) = h.iter().position(|v| !v.is_finite()) {
                return Err(ReferenceError::BadHeight { x: i % nx, y: i / nx, value: h[i] });
            }
        }
        let medium = TracedMedium::new(volume, MediumOptions { lookup, periodic: true, mask, ..Default::default() })?;
        Ok(MeasureScene { medium, height: height_map.map(|h| h.to_vec()), path: PathSettings::default() })
    }

    /// Texels along x and y (the volume's xres, yres).
    pub fn texels(&self) -> (usize, usize) {
        let [nx, ny, _] = self.medium.medium.dims();
        (nx, ny)
    }

    pub fn medium(&self) -> &TracedMedium<'v> {
        &self.medium
    }

    /// Surface height of texel (x, y), world z.
    pub fn height(&self, x: usize, y: usize) -> f32 {
        match &self.height {
            Some(h) => h[x + self.texels().0 * y],
            None => self.medium.medium.volume().bbox().max.z,
        }
    }

    /// One image of all texels for (ω_i, ω_o): pixel (c, r) is texel (x = c, y = r),
    /// so the image is `xres` wide and `yres` high, in texel order (not a camera view).
    pub fn render_image(&self, wi: Vec3, wo: Vec3, spp: u32, seed: u64) -> Result<(Image, PathStats), ReferenceError> {
        let (wi, wo) = check_pair(wi, wo)?;
        if spp == 0 {
            return Err(ReferenceError::ZeroSamples);
        }
        let (nx, ny) = self.texels();
        let light = Light::directional(wi, Vec3::ONE);
        let rows: Vec<(Vec<Vec3>, PathStats)> = (0..ny)
            .into_par_iter()
            .map(|y| {
                let mut stats = PathStats::default();
                let row = (0..nx)
                    .map(|x| {
                        let texel = (x + nx * y) as u64;
                        let mut sum = DVec3::ZERO;
                        for s in 0..spp {
                            let mut rng = Rng::new(seed, texel, s as u64);
                            sum += self.sample(x, y, wo, &light, &mut rng, &mut stats).as_dvec3();
                        }
                        (sum / spp as f64).as_vec3()
                    })
                    .collect();
                (row, stats)
            })
            .collect();
        let mut image = Image::new(nx as u32, ny as u32);
        let mut stats = PathStats::default();
        for (y, (row, s)) in rows.into_iter().enumerate() {
            image.pixels[y * nx..(y + 1) * nx].copy_from_slice(&row);
            stats.add(&s);
        }
        Ok((image, stats))
    }

    /// The dense measurement of one texel: the mean radiance of `spp` jittered samples
    /// for each (ω_i, ω_o) pair, in the order given.
    pub fn measure_texel(&self, texel: (usize, usize), pairs: &[(Vec3, Vec3)], spp: u32, seed: u64) -> Result<(Vec<Vec3>, PathStats), ReferenceError> {
        let (nx, ny) = self.texels();
        let (x, y) = texel;
        if x >= nx || y >= ny {
            return Err(ReferenceError::BadTexel { x, y, w: nx, h: ny });
        }
        if spp == 0 {
            return Err(ReferenceError::ZeroSamples);
        }
        let pairs: Vec<(Vec3, Vec3)> = pairs.iter().map(|&(wi, wo)| check_pair(wi, wo)).collect::<Result<_, _>>()?;
        let key = mix64(seed ^ mix64((x + nx * y) as u64));
        let chunks = spp.div_ceil(CHUNK);
        let sums: Vec<(DVec3, PathStats)> = (0..pairs.len() * chunks as usize)
            .into_par_iter()
            .map(|item| {
                let (p, c) = (item / chunks as usize, item as u32 % chunks);
                let (wi, wo) = pairs[p];
                let light = Light::directional(wi, Vec3::ONE);
                let mut stats = PathStats::default();
                let mut sum = DVec3::ZERO;
                for s in c * CHUNK..((c + 1) * CHUNK).min(spp) {
                    let mut rng = Rng::new(key, p as u64, s as u64);
                    sum += self.sample(x, y, wo, &light, &mut rng, &mut stats).as_dvec3();
                }
                (sum, stats)
            })
            .collect();
        let mut stats = PathStats::default();
        let values = sums
            .chunks(chunks as usize)
            .map(|per_pair| {
                let mut sum = DVec3::ZERO;
                for (v, s) in per_pair {
                    sum += *v;
                    stats.add(s);
                }
                (sum / spp as f64).as_vec3()
            })
            .collect();
        Ok((values, stats))
    }

    /// The ray of one sample: through the jittered surface point of texel (x, y),
    /// travelling along −ω_o, started where it enters the slab from ω_o's side.
    pub fn sample_ray(&self, x: usize, y: usize, u: f32, v: f32, wo: Vec3) -> (Vec3, Vec3) {
        let volume = self.medium.medium.volume();
        let (bbox, vs) = (volume.bbox(), volume.voxel_size());
        let s = Vec3::new(bbox.min.x + (x as f32 + u) * vs.x, bbox.min.y + (y as f32 + v) * vs.y, self.height(x, y));
        let z_start = if wo.z > 0.0 { bbox.max.z } else { bbox.min.z };
        let back = ((z_start - s.z) / wo.z).max(0.0);
        let mut origin = s + back * wo;
        // The sheet is periodic: move the origin back into the base tile by whole periods.
        let size = bbox.size();
        origin.x -= ((origin.x - bbox.min.x) / size.x).floor() * size.x;
        origin.y -= ((origin.y - bbox.min.y) / size.y).floor() * size.y;
        (origin, -wo)
    }

    fn sample(&self, x: usize, y: usize, wo: Vec3, light: &Light, rng: &mut Rng, stats: &mut PathStats) -> Vec3 {
        let (u, v) = rng.next_2d();
        let (origin, d) = self.sample_ray(x, y, u, v, wo);
        radiance(&self.medium, &Lighting::from(light), &self.path, origin, d, rng, stats)
    }
}

fn check_pair(wi: Vec3, wo: Vec3) -> Result<(Vec3, Vec3), ReferenceError> {
    let unit = |what, w: Vec3| {
        let n = w.normalize_or_zero();
        if !w.is_finite() || n == Vec3::ZERO { Err(ReferenceError::BadDirection { what, value: w }) } else { Ok(n) }
    };
    let (wi, wo) = (unit("light (ω_i)", wi)?, unit("view (ω_o)", wo)?);
    if wo.z.abs() < MIN_COS_VIEW {
        return Err(ReferenceError::GrazingDirection { what: "view (ω_o)", value: wo });
    }
    Ok((wi, wo))
}
