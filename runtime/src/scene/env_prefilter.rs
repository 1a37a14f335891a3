//! The prefiltered environment the model renderers light from (paper §7.2,
//! "Extensions": SG lobes lit by prefiltered environment maps).
//!
//! Two representations of one [`EnvMap`], in its own (u, v) parameterization:
//! - a chain of spherical-Gaussian blurs: level k holds
//!   ```text
//!   L̄_k(μ) = ∫ L(ω) e^{λ_k (μ·ω − 1)} dω / ∫ e^{λ_k (μ·ω − 1)} dω,   λ_k = 1/σ_k²,
//!   σ_k = σ_0 · 2^k
//!   ```
//!   (the mean radiance under a normalized SG of angular width σ_k) at a resolution
//!   whose texel is σ_k/2; σ_0 is two texel heights of the source map, and the chain
//!   ends when a level is 4 texels high. [`PrefilteredEnv::blurred`] reads the level
//!   nearest in log σ bilinearly, so an SG lobe of any width is one lookup: ∫ L(ω) A e^{λ(μ·ω−1)} dω ≈ A · 2π/λ · (1 − e^{−2λ}) · L̄_σ(μ).
//! - the irradiance map E(n) = ∫ L(ω) max(n·ω, 0) dω (the cosine convolution of the
//!   source map downsampled to at most 128 × 64, at 64 × 32 normals), for diffuse terms.
//!
//! # Two halves
//! The tile's plane is the map's horizon, and light reaches the tile's reflection lobes
//! only from above it and its transmission term only from below (cpu/env_shading.rs). A
//! blur of the whole map would carry light across the horizon: a grazing lobe's lookup
//! would read the ground, and a tilted normal's irradiance would gather light from below
//! the sheet (measured on a map lit only below: up to 7% of a tilted texel's diffuse
//! light and 30% of a grazing lobe's, runtime/ENV_MEASUREMENTS.md, "Light through the
//! cloth"). So there are two chains, each the normalized blur of one half alone (the sum
//! above over the texels on one side of the horizon, divided by the kernel's mass
//! there: the mean radiance of that half near μ), and a lookup reads the chain of its
//! own side. (The half's blur over the whole kernel's mass instead, the other half taken
//! as black, was measured too and drawn 10% darker and further from the path tracer:
//! runtime/ENV_MEASUREMENTS.md, "Light through the cloth".) Away from the horizon both
//! chains are the whole map's blur, so the background and a mesh's fragments, whose
//! horizon is not the map's, read them as they would the map's.
//! The irradiance map likewise gathers the upper half alone ([`PrefilteredEnv::irradiance`],
//! the reflection's diffuse term), beside one of the whole sphere
//! ([`PrefilteredEnv::irradiance_full`]: the transmission's diffuse term at −ẑ, and a
//! mesh's fragments). A constant map stays constant in both chains; on a tile the cut at
//! the horizon is what the path tracer's light does.
//!
//! Each level is computed from the source box-downsampled to its resolution (texels
//! weighted by solid angle) by a windowed convolution (±3σ) normalized by the kernel's
//! own discrete sum, so a constant map stays exactly constant at every level.

use std::f32::consts::PI;

use glam::Vec3;
use rayon::prelude::*;

use super::env_lights::{ExtractOptions, extract_lights};
use super::envmap::{EnvMap, EnvMapError, local_direction, row_solid_angle};
use super::light::Light;

/// One equirectangular level: row 0 at the map's zenith.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvLevel {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec3>,
}

impl EnvLevel {
    fn at(&self, x: usize, y: usize) -> Vec3 {
        self.texels[y * self.width as usize + x]
    }

    /// Bilinear lookup at (u, v) ∈ [0, 1]²: wraps in u, clamps in v.
    pub fn bilinear(&self, u: f32, v: f32) -> Vec3 {
        let (w, h) = (self.width as usize, self.height as usize);
        let x = u * w as f32 - 0.5;
        let y = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let xi = (x0 as i64).rem_euclid(w as i64) as usize;
        let x1 = (xi + 1) % w;
        let yi = y0 as usize;
        let y1 = (yi + 1).min(h - 1);
        let top = self.at(xi, yi).lerp(self.at(x1, yi), fx);
        let bottom = self.at(xi, y1).lerp(self.at(x1, y1), fx);
        top.lerp(bottom, fy)
    }

    /// Unit direction (map frame) of texel (x, y)'s centre.
    fn centre(&self, x: usize, y: usize) -> Vec3 {
        local_direction((x as f32 + 0.5) / self.width as f32, (y as f32 + 0.5) / self.height as f32)
    }
}

/// The SG-blur chain and irradiance map of an environment map, and the sources taken
/// out of it as directional lights (env_lights.rs), if any.
#[derive(Clone, Debug)]
pub struct PrefilteredEnv {
    /// The whole map (sources included), for the background and the placement.
    pub map: EnvMap,
    /// Sources shaded as lights; the chain holds the map without them.
    pub lights: Vec<Light>,
    /// σ of level 0 (radians).
    pub sigma0: f32,
    /// The chain of the half above the horizon (module docs, "Two halves").
    pub levels: Vec<EnvLevel>,
    /// The chain of the half below it, level for level.
    pub levels_below: Vec<EnvLevel>,
    /// E(n) gathered from the half above the horizon.
    pub irradiance: EnvLevel,
    /// E(n) gathered from the whole sphere.
    pub irradiance_full: EnvLevel,
    /// Whether any texel of the chain's map (sources out) below the horizon is lit
    /// ([`PrefilteredEnv::lights_below`]).
    pub below: bool,
}

/// Resolution of the irradiance map.
pub const IRRADIANCE_WIDTH: u32 = 64;

impl PrefilteredEnv {
    /// The map prefiltered whole (no lights taken out).
    pub fn new(map: &EnvMap) -> PrefilteredEnv {
        Self::build(map, map, Vec::new())
    }

    /// Compact bright sources become directional lights; the rest is prefiltered.
    pub fn with_lights(map: &EnvMap, options: ExtractOptions) -> Result<PrefilteredEnv, EnvMapError> {
        let (lights, rest) = extract_lights(map, options)?;
        Ok(Self::build(map, &rest, lights))
    }

    fn build(whole: &EnvMap, map: &EnvMap, lights: Vec<Light>) -> PrefilteredEnv {
        let source = EnvLevel { width: map.width(), height: map.height(), texels: (0..map.height()).flat_map(|y| (0..map.width()).map(move |x| (x, y))).map(|(x, y)| map.texel(x, y)).collect() };
        // Level 0 at the source's resolution (or 512 × 256 at most: finer adds nothing
        // for lobes wider than a few tenths of a degree).
        let mut base = source.clone();
        while base.height > 256 {
            base = downsample(&base);
        }
        let sigma0 = 2.0 * PI / base.height as f32;
        let mut levels = Vec::new();
        let mut levels_below = Vec::new();
        let mut input = base;
        let mut sigma = sigma0;
        loop {
            levels.push(sg_blur(&input, sigma, Half::Above));
            levels_below.push(sg_blur(&input, sigma, Half::Below));
            if input.height <= 4 {
                break;
            }
            input = downsample(&input);
            sigma *= 2.0;
        }
        let mut small = source;
        while small.width > 2 * IRRADIANCE_WIDTH && small.height > 1 {
            small = downsample(&small);
        }
        let (irradiance, irradiance_full) = cosine_convolution(&small, IRRADIANCE_WIDTH, IRRADIANCE_WIDTH / 2);
        let below = (0..map.height()).any(|y| map.direction(0.5, (y as f32 + 0.5) / map.height() as f32).z < 0.0 && (0..map.width()).any(|x| map.texel(x, y).max_element() > 0.0));
        PrefilteredEnv { map: whole.clone(), lights, sigma0, levels, levels_below, irradiance, irradiance_full, below }
    }

    /// The same environment turned to `rotate_deg` about +Z, as if it had been placed
    /// there (the window's live rotation): lookups go through the map's placement, so the
    /// chain and the irradiance map are kept, and the sources taken out as lights turn
    /// with it. Nothing is prefiltered again.
    pub fn rotated(&self, rotate_deg: f32) -> Result<PrefilteredEnv, EnvMapError> {
        let map = self.map.rotated(rotate_deg)?;
        let turn = glam::Quat::from_rotation_z((rotate_deg - self.map.rotate_deg()).to_radians());
        let lights = self
            .lights
            .iter()
            .map(|l| match *l {
                Light::Directional { dir_to_light, irradiance } => Light::directional(turn * dir_to_light, irradiance),
                other => other,
            })
            .collect();
        Ok(PrefilteredEnv { map, lights, sigma0: self.sigma0, levels: self.levels.clone(), levels_below: self.levels_below.clone(), irradiance: self.irradiance.clone(), irradiance_full: self.irradiance_full.clone(), below: self.below })
    }

    /// Whether the map (its sources taken out) sends any light up through the sheet:
    /// a texel whose centre lies below the horizon is lit (the rotation about +Z changes
    /// nothing). Both renderers light a model's transmission term by the map only then
    /// (cpu/env_shading.rs), so a map dark below the horizon costs a BSDF model nothing;
    /// its sources below the sheet are lights, which decide for themselves.
    pub fn lights_below(&self) -> bool {
        self.below
    }

    /// Widest σ the chain holds.
    pub fn sigma_max(&self) -> f32 {
        self.sigma0 * (1u32 << (self.levels.len() - 1)) as f32
    }

    /// L̄_σ toward world direction `w`: the mean radiance under a normalized SG of
    /// angular width σ (radians) around w, from the level nearest σ in log2 (σ below
    /// σ_0 reads level 0; above the chain's widest, its last level), of the map's half
    /// on w's side of the horizon (module docs, "Two halves").
    pub fn blurred(&self, w: Vec3, sigma: f32) -> Vec3 {
        let (u, v) = self.map.uv(w);
        let k = self.level_of(sigma);
        if w.z < 0.0 { self.levels_below[k].bilinear(u, v) } else { self.levels[k].bilinear(u, v) }
    }

    /// The level nearest σ in log σ, read bilinearly: half the fetches of blending two
    /// levels, for 0.25 points of median error (env_shading.rs's test: 1.87% → 2.1%).
    fn level_of(&self, sigma: f32) -> usize {
        let l = if sigma > self.sigma0 { (sigma / self.sigma0).log2() } else { 0.0 };
        (l.min((self.levels.len() - 1) as f32) + 0.5) as usize
    }

    /// E(n) = ∫_{ω·ẑ > 0} L(ω) max(n·ω, 0) dω for a world normal n: the light of the
    /// half above the horizon, what reaches a tile's reflection.
    pub fn irradiance(&self, n: Vec3) -> Vec3 {
        let (u, v) = self.map.uv(n);
        self.irradiance.bilinear(u, v)
    }

    /// E(n) = ∫ L(ω) max(n·ω, 0) dω over the whole sphere.
    pub fn irradiance_full(&self, n: Vec3) -> Vec3 {
        let (u, v) = self.map.uv(n);
        self.irradiance_full.bilinear(u, v)
    }
}

/// Integral of a unit-peak SG of sharpness λ over the sphere: 2π/λ · (1 − e^{−2λ}).
#[inline]
pub fn sg_integral(lambda: f32) -> f32 {
    2.0 * PI / lambda * (1.0 - (-2.0 * lambda).exp())
}

/// Halves each side (height stops at 1), averaging 2×2 texels by solid angle.
fn downsample(l: &EnvLevel) -> EnvLevel {
    let (w, h) = (l.width as usize, l.height as usize);
    let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
    let mut texels = vec![Vec3::ZERO; nw * nh];
    for y in 0..nh {
        for x in 0..nw {
            let mut sum = Vec3::ZERO;
            let mut wsum = 0.0f32;
            for sy in (2 * y)..(2 * y + 2).min(h) {
                let om = row_solid_angle(sy, h, w) as f32;
                for sx in (2 * x)..(2 * x + 2).min(w) {
                    sum += l.at(sx, sy) * om;
                    wsum += om;
                }
            }
            texels[y * nw + x] = if wsum > 0.0 { sum / wsum } else { Vec3::ZERO };
        }
    }
    EnvLevel { width: nw as u32, height: nh as u32, texels }
}

/// A side of the map's horizon (module docs, "Two halves"); a texel whose centre lies on
/// the horizon belongs to both.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Half {
    Above,
    Below,
}

impl Half {
    /// Whether map-frame direction `d` (Y up) is on this side (within rounding of the
    /// horizon: an odd-height map's middle row, whose centre is cos(π/2) ≈ −4e-8, is on
    /// both).
    fn holds(self, d: Vec3) -> bool {
        match self {
            Half::Above => d.y >= -1e-6,
            Half::Below => d.y <= 1e-6,
        }
    }
}

/// The normalized SG blur of `half` of `l` with width σ, at `l`'s resolution: each texel
/// the kernel-weighted mean of the texels of that half (0 where the kernel's ±3σ holds
/// none of them, texels no lookup of that side reads).
fn sg_blur(l: &EnvLevel, sigma: f32, half: Half) -> EnvLevel {
    let (w, h) = (l.width as usize, l.height as usize);
    let lambda = 1.0 / (sigma * sigma);
    let dirs: Vec<Vec3> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| l.centre(x, y)).collect();
    let omegas: Vec<f32> = (0..h).map(|y| row_solid_angle(y, h, w) as f32).collect();
    let dtheta = PI / h as f32;
    let reach = 3.0 * sigma;
    let rows: Vec<Vec<Vec3>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let theta = (y as f32 + 0.5) * dtheta;
            let y_lo = ((theta - reach) / dtheta).floor().max(0.0) as usize;
            let y_hi = (((theta + reach) / dtheta).ceil() as usize).min(h - 1);
            (0..w)
                .map(|x| {
                    let mu = dirs[y * w + x];
                    let mut sum = Vec3::ZERO;
                    let mut wsum = 0.0f32;
                    for sy in y_lo..=y_hi {
                        // Columns within reach: the row's smallest sin θ decides the span.
                        let st = {
                            let (a, b) = ((sy as f32 * dtheta).sin(), ((sy + 1) as f32 * dtheta).sin());
                            a.min(b).max(1e-6)
                        };
                        let span = (reach / st / (2.0 * PI / w as f32)).ceil() as i64 + 1;
                        let cols: Box<dyn Iterator<Item = usize>> = if 2 * span + 1 >= w as i64 { Box::new(0..w) } else { Box::new((-span..=span).map(|d| (x as i64 + d).rem_euclid(w as i64) as usize)) };
                        for sx in cols {
                            let d = dirs[sy * w + sx];
                            if !half.holds(d) {
                                continue;
                            }
                            let k = (lambda * (mu.dot(d) - 1.0)).exp() * omegas[sy];
                            sum += l.at(sx, sy) * k;
                            wsum += k;
                        }
                    }
                    if wsum > 0.0 { sum / wsum } else { Vec3::ZERO }
                })
                .collect()
        })
        .collect();
    EnvLevel { width: l.width, height: l.height, texels: rows.into_iter().flatten().collect() }
}

/// E(n) = ∫ L max(n·ω, 0) dω of the piecewise-constant map `l`, at `w` × `h` normals:
/// each texel split into cells of equal solid angle (2 × 2, more for small maps), so the
/// cosine is integrated over the texel rather than taken at its centre. Returns the
/// integral over the cells above the horizon, and over all of them.
fn cosine_convolution(l: &EnvLevel, w: u32, h: u32) -> (EnvLevel, EnvLevel) {
    let (lw, lh) = (l.width as usize, l.height as usize);
    // At least 256 cells around the equator whatever the map's size.
    let sub = (256 / lw).clamp(2, 32);
    let mut src: Vec<(Vec3, Vec3)> = Vec::with_capacity(lw * lh * sub * sub);
    for y in 0..lh {
        let (c0, c1) = ((PI * y as f32 / lh as f32).cos(), (PI * (y + 1) as f32 / lh as f32).cos());
        let cell = row_solid_angle(y, lh, lw) as f32 / (sub * sub) as f32;
        for x in 0..lw {
            let radiance = l.at(x, y) * cell;
            if radiance.max_element() <= 0.0 {
                continue;
            }
            for j in 0..sub {
                let v = (c0 + (j as f32 + 0.5) / sub as f32 * (c1 - c0)).clamp(-1.0, 1.0).acos() / PI;
                for i in 0..sub {
                    let u = (x as f32 + (i as f32 + 0.5) / sub as f32) / lw as f32;
                    src.push((local_direction(u, v), radiance));
                }
            }
        }
    }
    let out = EnvLevel { width: w, height: h, texels: Vec::new() };
    let (above, full): (Vec<Vec3>, Vec<Vec3>) = (0..(w * h) as usize)
        .into_par_iter()
        .map(|i| {
            let n = out.centre(i % w as usize, i / w as usize);
            let (mut above, mut below) = (Vec3::ZERO, Vec3::ZERO);
            for (d, lw) in &src {
                let e = *lw * n.dot(*d).max(0.0);
                if d.y > 0.0 { above += e } else { below += e }
            }
            (above, above + below)
        })
        .unzip();
    (EnvLevel { texels: above, ..out.clone() }, EnvLevel { texels: full, ..out })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Image;
    use crate::scene::{EnvMapOptions, Sky};

    #[test]
    fn a_constant_map_stays_constant_and_integrates_exactly() {
        let env = PrefilteredEnv::new(&EnvMap::constant(Vec3::splat(0.7)).unwrap());
        for (k, (a, b)) in env.levels.iter().zip(&env.levels_below).enumerate() {
            for (y, half, l) in [(0, Half::Above, a), (a.height as usize - 1, Half::Below, b)] {
                assert!(half.holds(l.centre(0, y)));
                assert!((0..l.width as usize).all(|x| (l.at(x, y) - Vec3::splat(0.7)).abs().max_element() < 1e-5), "level {k} {half:?}");
            }
        }
        for n in [Vec3::Z, Vec3::X, -Vec3::Z, Vec3::new(0.3, -0.5, 0.8).normalize(), Vec3::new(0.3, -0.5, -0.1).normalize()] {
            // ∫ 0.7 max(n·ω, 0) dω = 0.7 π, within the discretization of the cosine.
            let e = env.irradiance_full(n);
            assert!((e - Vec3::splat(0.7 * PI)).abs().max_element() < 0.01 * 0.7 * PI, "{e}");
            for sigma in [0.0, 0.3, 3.0] {
                assert!((env.blurred(n, sigma) - Vec3::splat(0.7)).abs().max_element() < 1e-5, "{n} σ {sigma}");
            }
        }
        // A one-row map (2×1): its row lies on the horizon and serves both halves.
        let img = Image::from_fn(2, 1, |_, _| Vec3::splat(0.7));
        let row = PrefilteredEnv::new(&EnvMap::from_image(&img, EnvMapOptions::default(), std::path::Path::new("row")).unwrap());
        for n in [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.3, -0.5, -0.1).normalize()] {
            assert!((row.blurred(n, 0.5) - Vec3::splat(0.7)).abs().max_element() < 1e-5, "2×1: {n} {}", row.blurred(n, 0.5));
        }
        // The upper half alone: π at the zenith, π/2 at the horizon, 0 at the nadir.
        for (n, share) in [(Vec3::Z, 1.0), (Vec3::X, 0.5), (-Vec3::Z, 0.0)] {
            let e = env.irradiance(n);
            assert!((e - Vec3::splat(0.7 * PI * share)).abs().max_element() < 0.012 * 0.7 * PI, "{n}: {e}");
        }
    }

    #[test]
    fn light_does_not_cross_the_horizon() {
        // A map lit only below (the sky upside down): the chain above reads nothing
        // however wide the blur, nor does the irradiance of upward normals, tilted or not;
        // the chain below and the whole sphere's irradiance hold it all.
        let sky = Sky::default().env_map(EnvMapOptions::default()).unwrap();
        let (w, h) = (sky.width(), sky.height());
        let lit_below = |x: u32, y: u32| if sky.direction(0.5, (y as f32 + 0.5) / h as f32).z < 0.0 { sky.texel(x, h - 1 - y) } else { Vec3::ZERO };
        let map = sky.with_texels((0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| lit_below(x, y)).collect()).unwrap();
        let env = PrefilteredEnv::new(&map);
        assert!(env.lights_below());
        let mut rng = crate::brdf::twin::SplitMix64(5);
        for _ in 0..300 {
            let d = rng.unit_vector();
            let up = Vec3::new(d.x, d.y, d.z.abs().max(1e-3)).normalize();
            for sigma in [0.0, 0.2, 1.0, 3.0] {
                assert_eq!(env.blurred(up, sigma), Vec3::ZERO, "{up} σ {sigma}");
                assert!(env.blurred(-up, sigma).max_element() > 0.0, "{} σ {sigma}", -up);
            }
            if up.z > 0.2 {
                assert!(env.irradiance(up).max_element() < 1e-6, "{up}: {}", env.irradiance(up));
            }
        }
        assert!(env.irradiance_full(-Vec3::Z).max_element() > 0.0 && env.irradiance(Vec3::X).max_element() < 1e-6);
        // And the sky the right way up keeps its ground below: a map black below sends
        // nothing there.
        let dark_below = sky.with_texels((0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| if sky.direction(0.5, (y as f32 + 0.5) / h as f32).z < 0.0 { Vec3::ZERO } else { sky.texel(x, y) }).collect()).unwrap();
        let up_only = PrefilteredEnv::new(&dark_below);
        assert!(!up_only.lights_below());
        assert_eq!(up_only.blurred(-Vec3::Z, 2.0), Vec3::ZERO);
        assert!(up_only.blurred(Vec3::X, 2.0).max_element() > 0.0);
    }

    #[test]
    fn a_rotated_environment_is_the_one_placed_there() {
        // Turning a prefiltered sky to 70° gives what prefiltering it placed at 70° gives:
        // the same lookups everywhere and the same extracted sun, with nothing rebuilt.
        let sky = Sky::default();
        let options = crate::scene::ExtractOptions::default();
        let at = |deg: f32| PrefilteredEnv::with_lights(&sky.env_map(EnvMapOptions { scale: 1.0, rotate_deg: deg }).unwrap(), options).unwrap();
        let (turned, placed) = (at(10.0).rotated(70.0).unwrap(), at(70.0));
        assert_eq!(turned.lights.len(), placed.lights.len());
        assert!(!placed.lights.is_empty(), "the sky's sun is taken out");
        for (a, b) in turned.lights.iter().zip(&placed.lights) {
            match (a, b) {
                (Light::Directional { dir_to_light: da, irradiance: ea }, Light::Directional { dir_to_light: db, irradiance: eb }) => {
                    assert!((*da - *db).length() < 1e-5 && (*ea - *eb).abs().max_element() < 1e-5 * eb.max_element(), "{a:?} vs {b:?}");
                }
                _ => panic!("the sources are directional lights"),
            }
        }
        let mut rng = crate::brdf::twin::SplitMix64(3);
        for _ in 0..200 {
            let w = rng.unit_vector();
            for sigma in [0.0, 0.1, 0.5] {
                let (a, b) = (turned.blurred(w, sigma), placed.blurred(w, sigma));
                assert!((a - b).abs().max_element() <= 1e-5 * b.max_element().max(1e-3), "{w} σ {sigma}: {a} vs {b}");
            }
            assert!((turned.irradiance(w) - placed.irradiance(w)).abs().max_element() <= 1e-5 * placed.irradiance(w).max_element().max(1e-3));
        }
        assert!(at(0.0).rotated(f32::NAN).is_err());
    }

    #[test]
    fn blurs_follow_the_sg_convolution() {
        // A small bright disk (the sky's sun alone): L̄_σ(μ) at angle α from the sun ≈
        // E_sun · e^{λ(cos α − 1)} / (2π/λ (1 − e^{−2λ})) for σ well above the disk.
        let sky = Sky { zenith: Vec3::ZERO, horizon: Vec3::ZERO, ground: Vec3::ZERO, sun_radius_deg: 1.0, ..Sky::default() };
        let map = sky.env_map(EnvMapOptions { scale: 1.0, rotate_deg: 40.0 }).unwrap();
        let env = PrefilteredEnv::new(&map);
        // The map turned 40° about +Z carries its sun with it.
        let (s40, c40) = 40f32.to_radians().sin_cos();
        let sun = Vec3::new(c40 * sky.sun_dir.x - s40 * sky.sun_dir.y, s40 * sky.sun_dir.x + c40 * sky.sun_dir.y, sky.sun_dir.z).normalize();
        let side = sun.cross(Vec3::Z).normalize();
        for sigma in [0.1f32, 0.2, 0.4] {
            let lambda = 1.0 / (sigma * sigma);
            for alpha in [0.0f32, 0.5 * sigma, sigma] {
                let mu = (sun * alpha.cos() + side * alpha.sin()).normalize();
                let expect = sky.sun_irradiance.x * (lambda * (alpha.cos() - 1.0)).exp() / sg_integral(lambda);
                let got = env.blurred(mu, sigma).x;
                assert!((got - expect).abs() < 0.08 * expect, "σ {sigma} α {alpha}: {got} vs {expect}");
            }
        }
        // The irradiance of a sun alone is E_sun · max(n·ω_sun, 0).
        for n in [sun, Vec3::Z, Vec3::new(1.0, 0.0, 0.2).normalize()] {
            let expect = sky.sun_irradiance.x * n.dot(sun).max(0.0);
            assert!((env.irradiance(n).x - expect).abs() < 0.03 * sky.sun_irradiance.x, "{} vs {expect}", env.irradiance(n).x);
            assert!((env.irradiance_full(n).x - expect).abs() < 0.03 * sky.sun_irradiance.x, "{} vs {expect}", env.irradiance_full(n).x);
        }
    }

    #[test]
    fn chain_shape() {
        let img = Image::from_fn(1024, 512, |x, y| Vec3::splat(((x ^ y) & 7) as f32));
        let env = PrefilteredEnv::new(&EnvMap::from_image(&img, EnvMapOptions::default(), std::path::Path::new("t")).unwrap());
        assert_eq!((env.levels[0].width, env.levels[0].height), (512, 256));
        assert_eq!(env.levels.last().unwrap().height, 4);
        assert!((env.sigma0 - 2.0 * PI / 256.0).abs() < 1e-6);
        assert_eq!(env.levels.len(), env.levels_below.len());
        assert!(env.levels.iter().chain(&env.levels_below).all(|l| l.texels.iter().all(|t| t.is_finite() && t.min_element() >= 0.0)));
    }
}
