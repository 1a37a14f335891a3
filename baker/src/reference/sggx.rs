//! The SGGX microflake distribution and its specular phase function
//! (Heitz, Dupuy, Crassin and Dachsbacher 2015, "The SGGX microflake distribution").
//!
//! S is a symmetric positive-definite 3×3 matrix, stored as (xx, yy, zz, xy, xz, yz),
//! the channel order of Mitsuba 3's `sggx` plugin. Fibers (docs/DESIGN.md §4):
//!
//!   S = σ²·ω_f ω_fᵀ + (I − ω_f ω_fᵀ) = I − (1 − σ²)·ω_f ω_fᵀ
//!
//! - projected area (paper Eq. 9):   σ(ω) = √(ωᵀ S ω)
//! - distribution of normals (Eq. 8): D(ω_m) = 1 / (π √|S| (ω_mᵀ S⁻¹ ω_m)²)
//!   evaluated through the adjugate, D = |S|^{3/2} / (π (ω_mᵀ adj(S) ω_m)²), which needs
//!   no inverse;
//! - visible normals (Eq. 3):        D_ωi(ω_m) = ⟨ω_i, ω_m⟩₊ D(ω_m) / σ(ω_i)
//! - specular phase function (Eq. 13): f_p(ω_i → ω_o) = D(ω_h) / (4 σ(ω_i)),
//!   ω_h = (ω_i + ω_o)/‖ω_i + ω_o‖.
//!
//! Directions: ω_i and ω_o both point *away* from the scattering point (ω_i = −ray
//! direction), as Mitsuba's `mi.wi`. Sampling reflects ω_i about a visible normal
//! drawn from D_ωi, so sample weight f_p / pdf = 1 exactly.
//!
//! D is normalized so that σ(ω) = ∫ ⟨ω, ω_m⟩₊ D(ω_m) dω_m (with S = I, D = 1/π and
//! the phase function is isotropic, 1/(4π)).

use glam::Vec3;

/// An SGGX matrix (xx, yy, zz, xy, xz, yz).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sggx {
    pub xx: f32,
    pub yy: f32,
    pub zz: f32,
    pub xy: f32,
    pub xz: f32,
    pub yz: f32,
}

impl Sggx {
    /// The identity: a spherical microflake distribution, isotropic phase function.
    pub const IDENTITY: Sggx = Sggx { xx: 1.0, yy: 1.0, zz: 1.0, xy: 0.0, xz: 0.0, yz: 0.0 };

    /// The fiber-like matrix S = I − (1 − σ²)·ω_f ω_fᵀ for a unit fiber direction.
    pub fn fiber(dir: Vec3, roughness: f32) -> Sggx {
        Sggx::from_fiber_moment(FiberMoment::of(dir), roughness)
    }

    /// S = I − (1 − σ²)·M for a (possibly interpolated) moment M = Σ wᵢ ω_fᵢ ω_fᵢᵀ
    /// with Σ wᵢ = 1: exactly the weighted sum of the fiber matrices, because S is
    /// affine in ω_f ω_fᵀ.
    #[inline]
    pub fn from_fiber_moment(m: FiberMoment, roughness: f32) -> Sggx {
        let k = 1.0 - roughness * roughness;
        Sggx { xx: 1.0 - k * m.xx, yy: 1.0 - k * m.yy, zz: 1.0 - k * m.zz, xy: -k * m.xy, xz: -k * m.xz, yz: -k * m.yz }
    }

    /// The six coefficients in Mitsuba 3's order.
    pub fn to_array(&self) -> [f32; 6] {
        [self.xx, self.yy, self.zz, self.xy, self.xz, self.yz]
    }

    /// ωᵀ S ω.
    #[inline]
    pub fn quadratic(&self, w: Vec3) -> f32 {
        w.x * w.x * self.xx + w.y * w.y * self.yy + w.z * w.z * self.zz + 2.0 * (w.x * w.y * self.xy + w.x * w.z * self.xz + w.y * w.z * self.yz)
    }

    /// σ(ω) = √(ωᵀ S ω), the projected area of the flakes seen along ±ω.
    #[inline]
    pub fn projected_area(&self, w: Vec3) -> f32 {
        self.quadratic(w).max(0.0).sqrt()
    }

    /// |S|.
    pub fn det(&self) -> f32 {
        self.xx * self.yy * self.zz - self.xx * self.yz * self.yz - self.yy * self.xz * self.xz - self.zz * self.xy * self.xy
            + 2.0 * self.xy * self.xz * self.yz
    }

    /// D(ω_m) for a unit normal ω_m.
    pub fn ndf(&self, wm: Vec3) -> f32 {
        let det = self.det().max(0.0);
        // ω_mᵀ adj(S) ω_m = |S| · ω_mᵀ S⁻¹ ω_m.
        let den = wm.x * wm.x * (self.yy * self.zz - self.yz * self.yz)
            + wm.y * wm.y * (self.xx * self.zz - self.xz * self.xz)
            + wm.z * wm.z * (self.xx * self.yy - self.xy * self.xy)
            + 2.0
                * (wm.x * wm.y * (self.xz * self.yz - self.zz * self.xy)
                    + wm.x * wm.z * (self.xy * self.yz - self.yy * self.xz)
                    + wm.y * wm.z * (self.xy * self.xz - self.xx * self.yz));
        if !(den > 0.0) {
            return 0.0;
        }
        det * det.sqrt() / (core::f32::consts::PI * den * den)
    }

    /// The specular microflake phase function f_p(ω_i → ω_o) = D(ω_h) / (4 σ(ω_i)),
    /// per steradian of ω_o. Zero in the measure-zero case ω_o = −ω_i.
    pub fn phase(&self, wi: Vec3, wo: Vec3) -> f32 {
        let h = wi + wo;
        let len2 = h.length_squared();
        let sigma = self.projected_area(wi);
        if !(len2 > 1e-12) || !(sigma > 0.0) {
            return 0.0;
        }
        0.25 * self.ndf(h / len2.sqrt()) / sigma
    }

    /// A normal drawn from the visible normals D_ωi (supplemental material of Heitz et
    /// al. 2015, "sampling the VNDF"): S is expressed in an orthonormal frame
    /// (ω_k, ω_j, ω_i); a cosine-distributed point (u, v, w) of the unit hemisphere is
    /// mapped by the matrix (M_k, M_j, M_i) that takes the hemisphere to the visible half
    /// of the ellipsoid.
    pub fn sample_visible_normal(&self, wi: Vec3, u1: f32, u2: f32) -> Vec3 {
        let (wk, wj) = wi.any_orthonormal_pair();
        let s_kk = self.quadratic(wk);
        let s_jj = self.quadratic(wj);
        let s_ii = self.quadratic(wi);
        let s_kj = self.bilinear(wk, wj);
        let s_ki = self.bilinear(wk, wi);
        let s_ji = self.bilinear(wj, wi);
        let det_kji = (s_kk * s_jj * s_ii - s_kj * s_kj * s_ii - s_ki * s_ki * s_jj - s_ji * s_ji * s_kk + 2.0 * s_kj * s_ki * s_ji).abs();
        let inv_sqrt_s_ii = 1.0 / s_ii.max(1e-30).sqrt();
        let tmp = (s_jj * s_ii - s_ji * s_ji).max(1e-30).sqrt();
        let m_k = Vec3::new(det_kji.sqrt() / tmp, 0.0, 0.0);
        let m_j = Vec3::new(-inv_sqrt_s_ii * (s_ki * s_ji - s_kj * s_ii) / tmp, inv_sqrt_s_ii * tmp, 0.0);
        let m_i = inv_sqrt_s_ii * Vec3::new(s_ki, s_ji, s_ii);
        // Cosine-distributed point of the hemisphere around +w.
        let r = u1.sqrt();
        let (sp, cp) = (core::f32::consts::TAU * u2).sin_cos();
        let (u, v) = (r * cp, r * sp);
        let w = (1.0 - u * u - v * v).max(0.0).sqrt();
        let m = (u * m_k + v * m_j + w * m_i).normalize_or(m_i.normalize_or(Vec3::Z));
        (m.x * wk + m.y * wj + m.z * wi).normalize_or(wi)
    }

    /// Samples ω_o from f_p(ω_i → ·): mirror ω_i about a visible normal. The sample
    /// weight f_p/pdf is exactly 1, so only the direction is returned.
    pub fn sample_phase(&self, wi: Vec3, u1: f32, u2: f32) -> Vec3 {
        let m = self.sample_visible_normal(wi, u1, u2);
        (2.0 * wi.dot(m) * m - wi).normalize_or(-wi)
    }

    /// aᵀ S b.
    #[inline]
    fn bilinear(&self, a: Vec3, b: Vec3) -> f32 {
        a.x * b.x * self.xx + a.y * b.y * self.yy + a.z * b.z * self.zz + (a.x * b.y + a.y * b.x) * self.xy + (a.x * b.z + a.z * b.x) * self.xz + (a.y * b.z + a.z * b.y) * self.yz
    }
}

/// The second moment ω_f ω_fᵀ of fiber directions (or a convex combination of them),
/// stored as (xx, yy, zz, xy, xz, yz). Interpolating it is interpolating S.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FiberMoment {
    pub xx: f32,
    pub yy: f32,
    pub zz: f32,
    pub xy: f32,
    pub xz: f32,
    pub yz: f32,
}

impl FiberMoment {
    #[inline]
    pub fn of(f: Vec3) -> FiberMoment {
        FiberMoment { xx: f.x * f.x, yy: f.y * f.y, zz: f.z * f.z, xy: f.x * f.y, xz: f.x * f.z, yz: f.y * f.z }
    }

    /// self + w·(f fᵀ).
    #[inline]
    pub fn add_weighted(&mut self, f: Vec3, w: f32) {
        let wf = w * f;
        self.xx += wf.x * f.x;
        self.yy += wf.y * f.y;
        self.zz += wf.z * f.z;
        self.xy += wf.x * f.y;
        self.xz += wf.x * f.z;
        self.yz += wf.y * f.z;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::rng::Rng;
    use core::f64::consts::PI;

    /// Midpoint quadrature over the sphere in (cos θ, φ): an equal-area grid, exact for
    /// constants; with n_mu × 2n_mu cells its error on these smooth integrands
    /// (σ ≥ 0.3) is far below the tolerances used.
    fn integrate_sphere(n_mu: usize, f: impl Fn(Vec3) -> f64) -> f64 {
        let n_phi = 2 * n_mu;
        let cell = (2.0 / n_mu as f64) * (2.0 * PI / n_phi as f64);
        let mut sum = 0.0;
        for i in 0..n_mu {
            let mu = -1.0 + (i as f64 + 0.5) * 2.0 / n_mu as f64;
            let s = (1.0 - mu * mu).sqrt();
            for j in 0..n_phi {
                let phi = (j as f64 + 0.5) * 2.0 * PI / n_phi as f64;
                sum += f(Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, mu as f32));
            }
        }
        sum * cell
    }

    fn test_matrices() -> Vec<Sggx> {
        vec![
            Sggx::IDENTITY,
            Sggx::fiber(Vec3::X, 0.5),
            Sggx::fiber(Vec3::Y, 0.3),
            Sggx::fiber(Vec3::new(0.6, 0.8, 0.0), 0.3),
            Sggx::fiber(Vec3::new(0.3, -0.5, 0.8).normalize(), 0.3),
            // A convex combination of two fibers (what trilinear interpolation makes).
            {
                let mut m = FiberMoment::default();
                m.add_weighted(Vec3::new(1.0, 1.0, 0.2).normalize(), 0.6);
                m.add_weighted(Vec3::new(-0.2, 1.0, -0.5).normalize(), 0.4);
                Sggx::from_fiber_moment(m, 0.4)
            },
        ]
    }

    #[test]
    fn fiber_matrix_has_the_fiber_eigenvalues() {
        let f = Vec3::new(0.3, -0.5, 0.8).normalize();
        let s = Sggx::fiber(f, 0.3);
        assert!((s.quadratic(f) - 0.09).abs() < 1e-6);
        let (a, b) = f.any_orthonormal_pair();
        assert!((s.quadratic(a) - 1.0).abs() < 1e-6 && (s.quadratic(b) - 1.0).abs() < 1e-6);
        assert!((s.det() - 0.09).abs() < 1e-5);
    }

    #[test]
    fn projected_area_matches_its_definition() {
        // σ(ω) = ∫ ⟨ω, ω_m⟩₊ D(ω_m) dω_m, by quadrature (400×800 cells).
        for s in test_matrices() {
            for w in [Vec3::Z, Vec3::X, Vec3::new(0.2, 0.9, -0.4).normalize()] {
                let integral = integrate_sphere(400, |m| (w.dot(m).max(0.0) * s.ndf(m)) as f64);
                let sigma = s.projected_area(w) as f64;
                assert!((integral - sigma).abs() < 2e-3 * sigma, "{s:?} {w}: ∫ = {integral}, σ = {sigma}");
            }
        }
    }

    #[test]
    fn phase_function_integrates_to_one() {
        for s in test_matrices() {
            for wi in [Vec3::Z, Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.3, 0.9, 0.3).normalize()] {
                let integral = integrate_sphere(400, |wo| s.phase(wi, wo) as f64);
                assert!((integral - 1.0).abs() < 2e-3, "{s:?} {wi}: ∫ f_p = {integral}");
                // Reciprocity of σ(ω_i) f_p(ω_i → ω_o) = D(ω_h)/4.
                let wo = Vec3::new(0.1, -0.7, 0.7).normalize();
                let (a, b) = (s.projected_area(wi) * s.phase(wi, wo), s.projected_area(wo) * s.phase(wo, wi));
                assert!((a - b).abs() <= 1e-5 * a.max(1e-6), "{a} vs {b}");
            }
        }
        let iso = Sggx::IDENTITY.phase(Vec3::Z, Vec3::new(0.0, 0.6, -0.8));
        assert!((iso - 0.25 / core::f32::consts::PI).abs() < 1e-6, "S = I is isotropic: {iso}");
    }

    /// Upper quantile of χ² with k degrees of freedom at significance α, by the
    /// Wilson–Hilferty approximation (accurate to a few % for k ≥ 10).
    fn chi2_critical(k: f64, z_alpha: f64) -> f64 {
        let a = 2.0 / (9.0 * k);
        k * (1.0 - a + z_alpha * a.sqrt()).powi(3)
    }

    #[test]
    fn sampled_directions_follow_the_phase_function() {
        // Pearson χ² of 100k samples in 16×32 equal-area (cos θ, φ) bins against the
        // integral of f_p over each bin (8×8 midpoint sub-cells); bins expecting < 5
        // are pooled. Significance 1e-4 (z = 3.72) per configuration.
        let (n_mu, n_phi, sub) = (16usize, 32usize, 8usize);
        let n_samples = 100_000u64;
        for (ci, s) in test_matrices().into_iter().enumerate() {
            for (wi_i, wi) in [Vec3::Z, Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.3, 0.9, 0.3).normalize(), Vec3::new(0.0, -0.85, 0.52).normalize()].into_iter().enumerate() {
                let mut observed = vec![0.0f64; n_mu * n_phi];
                let mut rng = Rng::new(99, (ci * 10 + wi_i) as u64, 0);
                for _ in 0..n_samples {
                    let wo = s.sample_phase(wi, rng.next_f32(), rng.next_f32());
                    assert!(wo.is_normalized(), "{wo}");
                    let i = (((wo.z as f64 + 1.0) * 0.5 * n_mu as f64) as usize).min(n_mu - 1);
                    let phi = (wo.y as f64).atan2(wo.x as f64).rem_euclid(2.0 * PI);
                    let j = ((phi / (2.0 * PI) * n_phi as f64) as usize).min(n_phi - 1);
                    observed[i * n_phi + j] += 1.0;
                }
                let mut expected = vec![0.0f64; n_mu * n_phi];
                let (dmu, dphi) = (2.0 / (n_mu * sub) as f64, 2.0 * PI / (n_phi * sub) as f64);
                for i in 0..n_mu * sub {
                    let mu = -1.0 + (i as f64 + 0.5) * dmu;
                    let st = (1.0 - mu * mu).sqrt();
                    for j in 0..n_phi * sub {
                        let phi = (j as f64 + 0.5) * dphi;
                        let wo = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, mu as f32);
                        expected[(i / sub) * n_phi + j / sub] += s.phase(wi, wo) as f64 * dmu * dphi * n_samples as f64;
                    }
                }
                let (mut chi2, mut dof, mut pooled_o, mut pooled_e) = (0.0, 0usize, 0.0, 0.0);
                for (o, e) in observed.iter().zip(&expected) {
                    if *e < 5.0 {
                        pooled_o += o;
                        pooled_e += e;
                    } else {
                        chi2 += (o - e) * (o - e) / e;
                        dof += 1;
                    }
                }
                if pooled_e >= 5.0 {
                    chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
                    dof += 1;
                }
                let crit = chi2_critical((dof - 1) as f64, 3.72);
                assert!(chi2 < crit, "matrix {ci}, ω_i {wi}: χ² = {chi2:.1} over {dof} bins (critical {crit:.1})");
            }
        }
    }

    #[test]
    fn degenerate_inputs_stay_finite() {
        let s = Sggx::fiber(Vec3::X, 0.01);
        for wi in [Vec3::X, -Vec3::X, Vec3::Z] {
            for (u1, u2) in [(0.0, 0.0), (0.999_999_9, 0.5), (0.5, 0.999_999_9)] {
                let wo = s.sample_phase(wi, u1, u2);
                assert!(wo.is_finite() && wo.is_normalized(), "{wi} {u1} {u2}: {wo}");
                assert!(s.phase(wi, wo).is_finite());
            }
        }
        assert_eq!(s.phase(Vec3::Z, -Vec3::Z), 0.0);
    }
}
