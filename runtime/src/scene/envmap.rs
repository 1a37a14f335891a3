//! Environment lighting: an equirectangular map of incident radiance at infinity, with
//! importance sampling (docs/DESIGN.md §8 conventions; paper §7.2 "Extensions").
//!
//! # Orientation (Mitsuba 3's `envmap`)
//! The map is addressed in its own frame, Y up, exactly as Mitsuba's `envmap` emitter:
//! for a local direction v (toward the light),
//! ```text
//! u = atan2(v.x, −v.z) / 2π  (wrapped into [0, 1)),   v_tex = acos(v.y) / π
//! ```
//! so row 0 is the zenith and u = 0 looks along −Z. Our scenes are Z up, so the map's
//! frame is placed in the world by `world = R_z(rotate) · R_x(+90°) · local`: the map's
//! up is world +Z and `rotate` (degrees) turns it about +Z. The Mitsuba scene that
//! matches `--envmap F --envmap-rotate R --envmap-scale S` is
//! `{'type': 'envmap', 'filename': F, 'scale': S,
//!   'to_world': T.rotate([0, 0, 1], R) @ T.rotate([1, 0, 0], 90)}`.
//!
//! # Lookup and sampling
//! A texel is constant over its (u, v) rectangle (nearest lookup; Mitsuba filters
//! bilinearly, so the two agree on maps smooth at the texel scale). Directions are
//! drawn texel by texel with probability ∝ mean(RGB) · Ω_texel through a marginal CDF
//! over rows and a conditional CDF per row, then uniformly in solid angle inside the
//! texel (u uniform, cos θ uniform), so the density per steradian is
//! ```text
//! p(ω) = P_texel / Ω_texel,   Ω_texel = (cos θ₀ − cos θ₁) · 2π / W
//! ```
//! `pdf` and `sample` agree exactly, every direction with non-zero radiance has non-zero
//! density (the estimator is unbiased), and a constant map is sampled with L/p = 4πL
//! exactly.

use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::brdf::cloth_atan2;
use crate::image::{Image, ImageError};

/// Largest map side accepted (16k × 8k is already 1.6 GB of f32 RGB).
pub const ENVMAP_MAX_SIDE: u32 = 16384;
/// The brightest texel accepted (after `scale`): far above a sun in any map's units (a
/// unit-irradiance sun in one texel of a 16384-wide map is ~7e6), far below where f32
/// sums of radiance × BRDF overflow (3.4e38 made pixels infinite).
pub const ENVMAP_MAX_RADIANCE: f32 = 1e15;

#[derive(Debug, thiserror::Error)]
pub enum EnvMapError {
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error("{path}: environment map is {width}x{height}; equirectangular maps need at least 2x1 texels and at most {ENVMAP_MAX_SIDE} per side")]
    BadSize { path: PathBuf, width: u32, height: u32 },
    #[error("{path}: texel ({x}, {y}) is {value}; environment radiance must be finite and non-negative")]
    BadTexel { path: PathBuf, x: u32, y: u32, value: Vec3 },
    #[error("{path}: texel ({x}, {y}) is {value} after --envmap-scale; environment radiance above {ENVMAP_MAX_RADIANCE:e} overflows the shading's f32 sums (scale the map down and raise --exposure)")]
    TooBright { path: PathBuf, x: u32, y: u32, value: Vec3 },
    #[error("--envmap-scale {0} must be finite and non-negative")]
    BadScale(f32),
    #[error("--envmap-rotate {0} must be finite (degrees)")]
    BadRotation(f32),
}

/// How the map is placed and scaled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvMapOptions {
    /// Multiplies every texel (Mitsuba's `scale`).
    pub scale: f32,
    /// Degrees about world +Z.
    pub rotate_deg: f32,
}

impl Default for EnvMapOptions {
    fn default() -> Self {
        EnvMapOptions { scale: 1.0, rotate_deg: 0.0 }
    }
}

/// One direction drawn from the map: toward the light, its radiance and its density
/// per steradian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    pub wi: Vec3,
    pub radiance: Vec3,
    pub pdf: f32,
}

/// An equirectangular environment map with its sampling tables.
#[derive(Clone, Debug)]
pub struct EnvMap {
    width: u32,
    height: u32,
    /// Radiance, scale applied; row 0 at the zenith.
    texels: Vec<Vec3>,
    rotate: f32,
    /// Row CDF, `height + 1` entries from 0 to 1.
    marginal: Vec<f32>,
    /// Per-row column CDF, `width + 1` entries each.
    conditional: Vec<f32>,
    /// Probability of each texel.
    texel_p: Vec<f32>,
    /// Where the image came from (for messages).
    name: PathBuf,
}

impl EnvMap {
    /// Reads `.exr` (linear RGB) or `.png` (sRGB decoded to linear).
    pub fn load(path: &Path, options: EnvMapOptions) -> Result<EnvMap, EnvMapError> {
        let image = Image::read(path, 1.0)?;
        EnvMap::from_image(&image, options, path)
    }

    /// Builds the map and its tables from a linear image; `name` labels errors.
    pub fn from_image(image: &Image, options: EnvMapOptions, name: &Path) -> Result<EnvMap, EnvMapError> {
        let (w, h) = (image.width, image.height);
        if w < 2 || h < 1 || w > ENVMAP_MAX_SIDE || h > ENVMAP_MAX_SIDE || image.pixels.len() != w as usize * h as usize {
            return Err(EnvMapError::BadSize { path: name.into(), width: w, height: h });
        }
        if !(options.scale.is_finite() && options.scale >= 0.0) {
            return Err(EnvMapError::BadScale(options.scale));
        }
        if !options.rotate_deg.is_finite() {
            return Err(EnvMapError::BadRotation(options.rotate_deg));
        }
        if let Some(i) = image.pixels.iter().position(|p| !(p.is_finite() && p.min_element() >= 0.0)) {
            return Err(EnvMapError::BadTexel { path: name.into(), x: i as u32 % w, y: i as u32 / w, value: image.pixels[i] });
        }
        let texels: Vec<Vec3> = image.pixels.iter().map(|p| *p * options.scale).collect();
        if let Some(i) = texels.iter().position(|t| !(t.max_element() <= ENVMAP_MAX_RADIANCE)) {
            return Err(EnvMapError::TooBright { path: name.into(), x: i as u32 % w, y: i as u32 / w, value: texels[i] });
        }
        // Texel weights: mean RGB times the texel's solid angle (∝ sin θ at the row centre).
        let (wu, hu) = (w as usize, h as usize);
        let mut conditional = vec![0.0f32; hu * (wu + 1)];
        let mut row_sum = vec![0.0f64; hu];
        for y in 0..hu {
            let omega = row_solid_angle(y, hu, wu);
            let mut acc = 0.0f64;
            let cdf = &mut conditional[y * (wu + 1)..(y + 1) * (wu + 1)];
            for x in 0..wu {
                let t = texels[y * wu + x];
                acc += (t.x as f64 + t.y as f64 + t.z as f64) / 3.0 * omega;
                cdf[x + 1] = acc as f32;
            }
            row_sum[y] = acc;
            normalize_cdf(cdf, acc);
        }
        let total: f64 = row_sum.iter().sum();
        let mut marginal = vec![0.0f32; hu + 1];
        let mut acc = 0.0f64;
        for y in 0..hu {
            acc += row_sum[y];
            marginal[y + 1] = acc as f32;
        }
        normalize_cdf(&mut marginal, total);
        let mut texel_p = vec![0.0f32; wu * hu];
        for y in (0..hu).filter(|_| total > 0.0) {
            let p_row = marginal[y + 1] - marginal[y];
            for x in 0..wu {
                let c = &conditional[y * (wu + 1)..];
                texel_p[y * wu + x] = p_row * (c[x + 1] - c[x]);
            }
        }
        Ok(EnvMap { width: w, height: h, texels, rotate: options.rotate_deg.to_radians(), marginal, conditional, texel_p, name: name.into() })
    }

    /// A map of one radiance everywhere (the furnace); refused like any texel if the
    /// radiance is negative or not finite.
    pub fn constant(radiance: Vec3) -> Result<EnvMap, EnvMapError> {
        let image = Image::from_fn(8, 4, |_, _| radiance);
        EnvMap::from_image(&image, EnvMapOptions::default(), Path::new("constant"))
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn name(&self) -> &Path {
        &self.name
    }

    /// The rotation about +Z (degrees).
    pub fn rotate_deg(&self) -> f32 {
        self.rotate.to_degrees()
    }

    /// The same texels turned to `rotate_deg` about +Z (finite degrees): its sampling
    /// tables are the texels' own, so they stay.
    pub fn rotated(&self, rotate_deg: f32) -> Result<EnvMap, EnvMapError> {
        if !rotate_deg.is_finite() {
            return Err(EnvMapError::BadRotation(rotate_deg));
        }
        Ok(EnvMap { rotate: rotate_deg.to_radians(), ..self.clone() })
    }

    /// The same placement with other (already scaled) texels, e.g. a map with its sun
    /// taken out.
    pub fn with_texels(&self, texels: Vec<Vec3>) -> Result<EnvMap, EnvMapError> {
        let image = Image { width: self.width, height: self.height, pixels: texels };
        let mut m = EnvMap::from_image(&image, EnvMapOptions { scale: 1.0, rotate_deg: 0.0 }, &self.name)?;
        m.rotate = self.rotate;
        Ok(m)
    }

    /// Radiance of texel (x, y), scale applied.
    pub fn texel(&self, x: u32, y: u32) -> Vec3 {
        self.texels[(y * self.width + x) as usize]
    }

    /// The map's frame from world directions (module docs).
    pub fn to_local(&self, w: Vec3) -> Vec3 {
        let (s, c) = self.rotate.sin_cos();
        // R_z(−rotate), then R_x(−90°): (x, y, z) ↦ (x, z, −y).
        let r = Vec3::new(c * w.x + s * w.y, -s * w.x + c * w.y, w.z);
        Vec3::new(r.x, r.z, -r.y)
    }

    /// World directions from the map's frame.
    pub fn to_world(&self, l: Vec3) -> Vec3 {
        placed(l, self.rotate)
    }

    /// Texture coordinates (u, v) ∈ [0, 1)² of a world direction toward the light.
    pub fn uv(&self, w: Vec3) -> (f32, f32) {
        // acos through the twins' own arctangent, so that env_shading.glsl's lookups
        // land on the same texels (GPUs' inverse trigonometry is their own).
        let l = self.to_local(w.normalize_or(Vec3::Z));
        let mut u = cloth_atan2(l.x, -l.z) / TAU;
        if u < 0.0 {
            u += 1.0;
        }
        let y = l.y.clamp(-1.0, 1.0);
        let v = cloth_atan2((1.0 - y * y).max(0.0).sqrt(), y) / PI;
        (u.min(ONE_MINUS), v.min(ONE_MINUS))
    }

    /// The world direction at texture coordinates (u, v).
    pub fn direction(&self, u: f32, v: f32) -> Vec3 {
        self.to_world(local_direction(u, v))
    }

    fn texel_index(&self, u: f32, v: f32) -> (usize, usize) {
        let x = ((u * self.width as f32) as usize).min(self.width as usize - 1);
        let y = ((v * self.height as f32) as usize).min(self.height as usize - 1);
        (x, y)
    }

    /// Radiance arriving from world direction `w` (toward the light).
    pub fn eval(&self, w: Vec3) -> Vec3 {
        let (u, v) = self.uv(w);
        let (x, y) = self.texel_index(u, v);
        self.texels[y * self.width as usize + x]
    }

    /// Density per steradian with which [`EnvMap::sample`] draws `w`.
    pub fn pdf(&self, w: Vec3) -> f32 {
        let (u, v) = self.uv(w);
        let (x, y) = self.texel_index(u, v);
        self.pdf_at(self.texel_p[y * self.width as usize + x], y)
    }

    fn pdf_at(&self, p_texel: f32, y: usize) -> f32 {
        let omega = row_solid_angle(y, self.height as usize, self.width as usize) as f32;
        if !(p_texel > 0.0) || !(omega > 0.0) {
            return 0.0;
        }
        p_texel / omega
    }

    /// Draws a direction ∝ radiance · solid angle from two uniform numbers in [0, 1).
    /// A map that is black everywhere returns a zero sample (pdf 0).
    pub fn sample(&self, u1: f32, u2: f32) -> EnvSample {
        if !(self.marginal[self.height as usize] > 0.0) {
            return EnvSample { wi: Vec3::Z, radiance: Vec3::ZERO, pdf: 0.0 };
        }
        let (y, fy) = sample_cdf(&self.marginal, u1);
        let row = &self.conditional[y * (self.width as usize + 1)..(y + 1) * (self.width as usize + 1)];
        let (x, fx) = sample_cdf(row, u2);
        let u = (x as f32 + fx) / self.width as f32;
        // Uniform in cos θ between the row's edges: uniform in solid angle.
        let (c0, c1) = ((PI * y as f32 / self.height as f32).cos(), (PI * (y + 1) as f32 / self.height as f32).cos());
        let cos_theta = (c0 + fy * (c1 - c0)).clamp(-1.0, 1.0);
        let v = (cos_theta.acos() / PI).clamp(y as f32 / self.height as f32, ((y + 1) as f32 / self.height as f32) * ONE_MINUS);
        let p_texel = self.texel_p[y * self.width as usize + x];
        let pdf = self.pdf_at(p_texel, y);
        let radiance = if pdf > 0.0 { self.texels[y * self.width as usize + x] } else { Vec3::ZERO };
        EnvSample { wi: self.direction(u, v), radiance, pdf }
    }

    /// ∫ L(ω) dΩ per channel (the map's power per unit area perpendicular, summed over
    /// directions): Σ texel · Ω_texel, exact for a piecewise-constant map.
    pub fn integral(&self) -> Vec3 {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut sum = glam::DVec3::ZERO;
        for y in 0..h {
            let omega = row_solid_angle(y, h, w);
            for x in 0..w {
                sum += self.texels[y * w + x].as_dvec3() * omega;
            }
        }
        sum.as_vec3()
    }
}

const ONE_MINUS: f32 = 1.0 - f32::EPSILON / 2.0;

/// A map-frame direction placed in the world: R_x(+90°) (the map's Y up becomes +Z),
/// then `rotate` radians about +Z.
#[inline]
pub fn placed(l: Vec3, rotate: f32) -> Vec3 {
    let r = Vec3::new(l.x, -l.z, l.y);
    let (s, c) = rotate.sin_cos();
    Vec3::new(c * r.x - s * r.y, s * r.x + c * r.y, r.z)
}

/// The direction at (u, v) in the map's own frame (Y up): θ = vπ from +Y, φ = 2πu
/// from −Z toward +X, Mitsuba's `envmap` parameterization.
#[inline]
pub fn local_direction(u: f32, v: f32) -> Vec3 {
    let (st, ct) = (v * PI).sin_cos();
    let (sp, cp) = (u * TAU).sin_cos();
    Vec3::new(st * sp, ct, -st * cp)
}

/// Solid angle of one texel of row `y` in a `w` × `h` map.
pub fn row_solid_angle(y: usize, h: usize, w: usize) -> f64 {
    let (t0, t1) = (std::f64::consts::PI * y as f64 / h as f64, std::f64::consts::PI * (y + 1) as f64 / h as f64);
    (t0.cos() - t1.cos()) * std::f64::consts::TAU / w as f64
}

fn normalize_cdf(cdf: &mut [f32], total: f64) {
    let n = cdf.len() - 1;
    if total > 0.0 {
        for c in cdf.iter_mut() {
            *c = (*c as f64 / total) as f32;
        }
    } else {
        // A black row: never drawn (its marginal mass is 0), but keep the CDF valid.
        for (i, c) in cdf.iter_mut().enumerate() {
            *c = i as f32 / n as f32;
        }
    }
    cdf[n] = 1.0;
}

/// The bin i with cdf[i] ≤ u < cdf[i+1] among bins of non-zero mass, and u's offset
/// inside it in [0, 1).
fn sample_cdf(cdf: &[f32], u: f32) -> (usize, f32) {
    let n = cdf.len() - 1;
    // First index with cdf[i] > u, minus one.
    let mut i = cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
    // Skip zero-mass bins (possible at u exactly on a plateau).
    while i + 1 < n && cdf[i + 1] <= cdf[i] {
        i += 1;
    }
    while i > 0 && cdf[i + 1] <= cdf[i] {
        i -= 1;
    }
    let mass = cdf[i + 1] - cdf[i];
    let f = if mass > 0.0 { ((u - cdf[i]) / mass).clamp(0.0, ONE_MINUS) } else { 0.5 };
    (i, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hash_f(i: u64) -> f32 {
        let mut z = i.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    fn test_map(rotate: f32) -> EnvMap {
        let img = Image::from_fn(16, 8, |x, y| Vec3::new(0.1 + (x % 5) as f32, (y as f32 * 0.7).sin().abs() + 0.05 * x as f32, if x == 3 && y == 2 { 40.0 } else { 0.0 }));
        EnvMap::from_image(&img, EnvMapOptions { scale: 2.0, rotate_deg: rotate }, Path::new("test")).unwrap()
    }

    #[test]
    fn orientation_matches_mitsuba() {
        let m = test_map(0.0);
        // Map up is world +Z; u = 0 (local −Z) is world +Y; u = 1/4 (local +X) is world +X.
        assert!((m.direction(0.3, 0.0) - Vec3::Z).length() < 1e-5);
        assert!((m.direction(0.0, 0.5) - Vec3::Y).length() < 1e-5);
        assert!((m.direction(0.25, 0.5) - Vec3::X).length() < 1e-5);
        let r = test_map(90.0);
        assert!((r.direction(0.25, 0.5) - Vec3::Y).length() < 1e-5, "rotation turns about +Z");
        for i in 0..200 {
            let (u, v) = (hash_f(2 * i), 0.02 + 0.96 * hash_f(2 * i + 1));
            let (u2, v2) = r.uv(r.direction(u, v));
            assert!((u - u2).abs() < 1e-4 && (v - v2).abs() < 1e-4, "uv round trip ({u}, {v}) → ({u2}, {v2})");
        }
    }

    #[test]
    fn pdf_integrates_to_one_and_matches_samples() {
        let m = test_map(30.0);
        // ∫ p dΩ over a fine (θ, φ) grid.
        let (nt, np) = (400, 800);
        let mut total = 0.0f64;
        for i in 0..nt {
            let theta = PI * (i as f32 + 0.5) / nt as f32;
            for j in 0..np {
                let phi = TAU * (j as f32 + 0.5) / np as f32;
                let l = Vec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos());
                total += m.pdf(m.to_world(l)) as f64 * theta.sin() as f64 * (PI / nt as f32) as f64 * (TAU / np as f32) as f64;
            }
        }
        assert!((total - 1.0).abs() < 5e-3, "∫ pdf = {total}");
        // Samples: pdf agrees with pdf(direction), and E[L/p] = ∫ L dΩ.
        let n = 200_000;
        let mut est = glam::DVec3::ZERO;
        let mut off = 0;
        for i in 0..n {
            let s = m.sample(hash_f(2 * i), hash_f(2 * i + 1));
            assert!(s.pdf > 0.0 && s.radiance.is_finite());
            // A sample on a texel edge may round into the neighbour (float round trip).
            off += ((m.pdf(s.wi) - s.pdf).abs() > 1e-3 * s.pdf) as u32;
            est += (s.radiance / s.pdf).as_dvec3();
        }
        assert!(off < n as u32 / 5000, "{off} of {n} samples disagree with pdf()");
        let est = (est / n as f64).as_vec3();
        let exact = m.integral();
        for c in 0..3 {
            assert!((est[c] - exact[c]).abs() < 0.01 * exact[c], "channel {c}: estimate {est} vs ∫L = {exact}");
        }
    }

    #[test]
    fn constant_map_integral_is_four_pi_l() {
        let m = EnvMap::constant(Vec3::splat(0.5)).unwrap();
        assert!((m.integral() - Vec3::splat(2.0 * PI)).abs().max_element() < 1e-4);
        let s = m.sample(0.3, 0.7);
        assert!((s.radiance / s.pdf - Vec3::splat(2.0 * PI)).abs().max_element() < 1e-3, "constant map: L/p = 4πL");
    }

    #[test]
    fn bad_maps_are_refused() {
        let ok = EnvMapOptions::default();
        let nan = Image::from_fn(4, 2, |x, y| if x == 2 && y == 1 { Vec3::new(0.0, f32::NAN, 0.0) } else { Vec3::ONE });
        let e = EnvMap::from_image(&nan, ok, Path::new("x.exr")).unwrap_err().to_string();
        assert!(e.contains("(2, 1)") && e.contains("x.exr"), "{e}");
        let neg = Image::from_fn(4, 2, |_, _| Vec3::new(1.0, -1.0, 0.0));
        assert!(matches!(EnvMap::from_image(&neg, ok, Path::new("n")), Err(EnvMapError::BadTexel { .. })));
        assert!(matches!(EnvMap::from_image(&Image::new(1, 1), ok, Path::new("s")), Err(EnvMapError::BadSize { .. })));
        assert!(matches!(EnvMap::from_image(&Image::new(4, 2), EnvMapOptions { scale: f32::INFINITY, ..ok }, Path::new("s")), Err(EnvMapError::BadScale(_))));
        assert!(matches!(EnvMap::from_image(&Image::new(4, 2), EnvMapOptions { rotate_deg: f32::NAN, ..ok }, Path::new("s")), Err(EnvMapError::BadRotation(_))));
        assert!(matches!(EnvMap::constant(Vec3::new(0.0, f32::INFINITY, 0.0)), Err(EnvMapError::BadTexel { .. })));
        // Finite but overflowing once shaded: refused, with the scale taken into account.
        let max = Image::from_fn(4, 2, |x, y| if x == 3 && y == 0 { Vec3::splat(f32::MAX) } else { Vec3::ONE });
        let e = EnvMap::from_image(&max, ok, Path::new("m.exr")).unwrap_err();
        assert!(matches!(e, EnvMapError::TooBright { x: 3, y: 0, .. }), "{e}");
        assert!(matches!(EnvMap::from_image(&Image::from_fn(4, 2, |_, _| Vec3::splat(1e9)), EnvMapOptions { scale: 1e7, ..ok }, Path::new("s")), Err(EnvMapError::TooBright { .. })));
        assert!(EnvMap::from_image(&Image::from_fn(4, 2, |_, _| Vec3::splat(1e9)), ok, Path::new("s")).is_ok());
        // A black map is valid and samples nothing.
        let black = EnvMap::from_image(&Image::new(4, 2), ok, Path::new("b")).unwrap();
        assert_eq!(black.sample(0.5, 0.5).pdf, 0.0);
        assert_eq!(black.pdf(Vec3::Z), 0.0);
    }
}
