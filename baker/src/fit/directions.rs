//! The (ω_i, ω_o) configurations of the fit (paper §5.3.1: "m configurations") and of
//! its held-out checks.
//!
//! Directions are in tile space (x, y along the tile, z up); both lie in the upper
//! hemisphere (transmission is not fitted). The training set is:
//! - **specular pairs**: ω_o the mirror of ω_i about +Z, the peak of every lobe of a
//!   flat texel whatever its tangent, with ω_i in the planes of the warp (x) and the
//!   weft (y) and the diagonals, at several polar angles;
//! - **cone pairs**: ω_o on the specular cone θ_o = −θ_i of a fiber along x, then along
//!   y, away from the mirror direction (what distinguishes a fiber's lobe from a
//!   mirror's);
//! - **stratified pairs**: the rest, ω_i and ω_o each stratified uniformly in solid
//!   angle over the cap θ ≤ `max_polar_deg`.
//!
//! Held-out pairs come from another seed and are kept only when at least
//! `min_separation_deg` from every training pair (the larger of the angles between the
//! two lights and between the two views).

use glam::Vec3;

use crate::reference::rng::Rng;

/// What a configuration is for (reported, and used to split residuals).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PairKind {
    Specular,
    Cone,
    Stratified,
}

/// One light/view pair, both unit, pointing away from the surface.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Pair {
    #[serde(serialize_with = "as_array")]
    pub wi: Vec3,
    #[serde(serialize_with = "as_array")]
    pub wo: Vec3,
    pub kind: PairKind,
}

fn as_array<S: serde::Serializer>(v: &Vec3, s: S) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&v.to_array(), s)
}

impl Pair {
    /// The larger of the polar angles of ω_i and ω_o, degrees.
    pub fn max_polar_deg(&self) -> f32 {
        self.wi.z.min(self.wo.z).clamp(-1.0, 1.0).acos().to_degrees()
    }

    /// Angular distance to another pair: the larger of ∠(ω_i, ω_i') and ∠(ω_o, ω_o'), degrees.
    pub fn distance_deg(&self, o: &Pair) -> f32 {
        let a = self.wi.dot(o.wi).clamp(-1.0, 1.0).acos();
        let b = self.wo.dot(o.wo).clamp(-1.0, 1.0).acos();
        a.max(b).to_degrees()
    }
}

/// How the configurations are chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct PairOptions {
    /// Number of training pairs m (≥ 8).
    pub count: usize,
    /// Largest polar angle of either direction, degrees.
    pub max_polar_deg: f32,
    pub seed: u64,
}

impl Default for PairOptions {
    fn default() -> Self {
        PairOptions { count: 40, max_polar_deg: 65.0, seed: 1 }
    }
}

/// Unit direction at polar θ, azimuth φ (degrees).
pub fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    fabric_runtime::scene::direction_from_angles(theta_deg, phi_deg)
}

/// Mirror of `w` about +Z.
pub fn mirror(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// The backlit configurations of a BSDF fit: each pair with its light mirrored through
/// the tile plane (ω_i.z < 0, below the sheet; the view stays above). A specular pair
/// becomes a straight-through pair (ω_o = −ω_i), the transmission lobe's peak.
pub fn backlit_pairs(pairs: &[Pair]) -> Vec<Pair> {
    pairs.iter().map(|p| Pair { wi: fabric_runtime::brdf::cloth_mirror_z(p.wi), ..*p }).collect()
}

/// A direction uniform in solid angle over the cap θ ≤ θ_max, from (u, v) ∈ [0, 1)².
fn cap(u: f32, v: f32, cos_max: f32) -> Vec3 {
    let z = 1.0 - u * (1.0 - cos_max);
    let s = (1.0 - z * z).max(0.0).sqrt();
    let p = std::f32::consts::TAU * v;
    Vec3::new(s * p.cos(), s * p.sin(), z)
}

/// ω_o on the specular cone of a fiber along unit `t` (θ_o = −θ_i), rotated by `turn`
/// radians about t from the mirror direction; `None` if it points below `cos_max`.
fn cone(wi: Vec3, t: Vec3, turn: f32, cos_max: f32) -> Option<Vec3> {
    let m = mirror(wi);
    // Rotate the mirror direction about t (Rodrigues): it stays on the cone.
    let (s, c) = turn.sin_cos();
    let wo = m * c + t.cross(m) * s + t * t.dot(m) * (1.0 - c);
    (wo.z >= cos_max).then_some(wo.normalize())
}

/// The m training configurations.
pub fn training_pairs(o: &PairOptions) -> Vec<Pair> {
    let cos_max = o.max_polar_deg.to_radians().cos();
    let m = o.count.max(8);
    let mut out = Vec::with_capacity(m);
    // Specular: a quarter of the set, in the warp, weft and diagonal planes.
    let polar: Vec<f32> = [15.0f32, 35.0, 55.0].into_iter().filter(|p| *p <= o.max_polar_deg).collect();
    'spec: for &theta in &polar {
        for phi in [0.0f32, 90.0, 45.0, 135.0] {
            if out.len() >= m / 4 {
                break 'spec;
            }
            let wi = dir(theta, phi);
            out.push(Pair { wi, wo: mirror(wi), kind: PairKind::Specular });
        }
    }
    // Cone pairs of fibers along x and along y: an eighth of the set.
    let target = out.len() + m / 8;
    'cone: for turn in [0.5f32, -0.5, 0.9, -0.9, 1.3, -1.3] {
        for (t, phi) in [(Vec3::X, 0.0f32), (Vec3::Y, 90.0)] {
            if out.len() >= target {
                break 'cone;
            }
            let wi = dir(40.0, phi + 20.0);
            if let Some(wo) = cone(wi, t, turn, cos_max) {
                out.push(Pair { wi, wo, kind: PairKind::Cone });
            }
        }
    }
    // Stratified over the rest: a √n×√n grid of strata for each direction, paired by a
    // seeded shuffle.
    let rest = m - out.len();
    let side = (rest as f32).sqrt().ceil() as usize;
    let mut rng = Rng::new(o.seed, 0x7061_6972, 0);
    let strata = |rng: &mut Rng| {
        let mut v: Vec<Vec3> = (0..side * side).map(|k| cap(((k / side) as f32 + rng.next_f32()) / side as f32, ((k % side) as f32 + rng.next_f32()) / side as f32, cos_max)).collect();
        shuffle(&mut v, rng);
        v
    };
    let (wis, wos) = (strata(&mut rng), strata(&mut rng));
    out.extend(wis.into_iter().zip(wos).take(rest).map(|(wi, wo)| Pair { wi, wo, kind: PairKind::Stratified }));
    out
}

/// `count` held-out pairs, each ≥ `min_separation_deg` from every pair of `training`,
/// with polar angles up to `max_polar_deg`: first the specular configurations across
/// warp and weft (azimuths between the training ones), then random pairs.
pub fn held_out_pairs(training: &[Pair], count: usize, max_polar_deg: f32, min_separation_deg: f32, seed: u64) -> Vec<Pair> {
    let cos_max = max_polar_deg.to_radians().cos();
    let far = |p: &Pair| training.iter().all(|t| p.distance_deg(t) >= min_separation_deg);
    let mut out = Vec::with_capacity(count);
    for (theta, phi) in [(45.0f32, 10.0f32), (25.0, 100.0), (58.0, 170.0), (42.0, 260.0)] {
        let wi = dir(theta.min(max_polar_deg), phi);
        let p = Pair { wi, wo: mirror(wi), kind: PairKind::Specular };
        if out.len() < count / 2 && far(&p) {
            out.push(p);
        }
    }
    let mut rng = Rng::new(seed, 0x686f_6c64, 0);
    let mut tries = 0;
    while out.len() < count && tries < 100_000 {
        tries += 1;
        let p = Pair { wi: cap(rng.next_f32(), rng.next_f32(), cos_max), wo: cap(rng.next_f32(), rng.next_f32(), cos_max), kind: PairKind::Stratified };
        if far(&p) {
            out.push(p);
        }
    }
    out
}

fn shuffle<T>(v: &mut [T], rng: &mut Rng) {
    for i in (1..v.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        v.swap(i, j);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn training_pairs_stay_in_the_cap_and_include_specular_and_cone_pairs() {
        let o = PairOptions { count: 40, max_polar_deg: 65.0, seed: 3 };
        let pairs = training_pairs(&o);
        assert_eq!(pairs.len(), 40);
        let cos_max = 65f32.to_radians().cos() - 1e-5;
        for p in &pairs {
            assert!(p.wi.z >= cos_max && p.wo.z >= cos_max, "{p:?}");
            assert!((p.wi.length() - 1.0).abs() < 1e-5 && (p.wo.length() - 1.0).abs() < 1e-5);
        }
        let count = |k| pairs.iter().filter(|p| p.kind == k).count();
        assert_eq!(count(PairKind::Specular), 10);
        assert_eq!(count(PairKind::Cone), 5);
        // Cone pairs keep θ_o = −θ_i for their fiber (x or y).
        for p in pairs.iter().filter(|p| p.kind == PairKind::Cone) {
            assert!((p.wi.x + p.wo.x).abs() < 1e-5 || (p.wi.y + p.wo.y).abs() < 1e-5, "{p:?}");
        }
        assert_eq!(pairs, training_pairs(&o), "deterministic");
    }

    #[test]
    fn held_out_pairs_keep_their_distance() {
        let training = training_pairs(&PairOptions::default());
        let held = held_out_pairs(&training, 10, 60.0, 5.0, 9);
        assert_eq!(held.len(), 10);
        assert!(held.iter().any(|p| p.kind == PairKind::Specular));
        for h in &held {
            assert!(h.max_polar_deg() <= 60.0 + 1e-3);
            for t in &training {
                assert!(h.distance_deg(t) >= 5.0);
            }
        }
    }
}
