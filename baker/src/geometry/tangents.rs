//! The tangent map t (paper §5.2, DESIGN.md §5): the fiber direction at the surface,
//! projected into the tangent plane and orthonormalized against n.
//!
//! - Fiber directions are axes (ω ≡ −ω), so the top `depth` voxels of the column's
//!   surface run are averaged as the coverage-weighted tensor M = Σ c·ω ωᵀ, whose
//!   principal eigenvector is the mean axis; averaging ±ω as vectors could cancel.
//! - t = normalize(e − (e·n) n): in the tangent plane, unit, ⟂ n.
//! - Sign convention: t·(x̂ + ŷ) ≥ 0 (ties: t.x ≥ 0, then t.z ≥ 0). Woven fibers run
//!   along x (weft) or y (warp); this picks +x̂ for the one and +ŷ for the other, both far
//!   from the flip at t ∥ x̂ − ŷ, so the map has no sign seams inside a yarn (t·(1, ε, 0)
//!   would flip on every warp yarn, with the x component's noise). The BRDF does not
//!   depend on the sign (t → −t mirrors θ and φ, and its lobes are even), but a stable
//!   sign keeps the map readable and filter-friendly.
//! - Fallback, counted and reported: a hole (no surface voxel) or a fiber axis within
//!   ~3° of the normal (|e − (e·n)n| < 0.05) has no usable direction; t is then x̂
//!   projected into the tangent plane (ŷ where n is within ~3° of x̂), deterministic.

use glam::{Mat3, Vec3};
use rayon::prelude::*;

use super::Progress;
use super::heightmap::DensityScale;
use crate::volume::FabricVolume;

/// The tangent map and how many texels fell back.
#[derive(Clone, Debug, PartialEq)]
pub struct TangentMap {
    pub tangents: Vec<Vec3>,
    pub fallback_texels: usize,
}

/// Smallest |projected axis| accepted (sin of ~3° between the fiber and the normal).
const MIN_PROJECTED: f32 = 0.05;

pub(crate) fn tangent_map(volume: &FabricVolume, density: &DensityScale, surface_top: &[i32], normals: &[Vec3], depth: usize, progress: &dyn Progress) -> TangentMap {
    let [nx, ny, _] = volume.dims();
    let rows: Vec<(Vec<Vec3>, usize)> = (0..ny)
        .into_par_iter()
        .map(|j| {
            let mut fallbacks = 0;
            let row = (0..nx)
                .map(|i| {
                    let n = normals[i + nx * j];
                    let axis = (surface_top[i + nx * j] >= 0).then(|| {
                        let top = surface_top[i + nx * j] as usize;
                        let mut m = Mat3::ZERO;
                        for z in (top.saturating_sub(depth - 1)..=top).rev() {
                            let v = volume.voxel(i, j, z);
                            let c = density.coverage(v.density());
                            if c == 0.0 {
                                break; // end of the surface run
                            }
                            let w = v.orientation();
                            m += Mat3::from_cols(w * w.x, w * w.y, w * w.z) * c;
                        }
                        principal_axis(m)
                    });
                    match axis.flatten().and_then(|e| tangent_from_axis(e, n)) {
                        Some(t) => t,
                        None => {
                            fallbacks += 1;
                            fallback_tangent(n)
                        }
                    }
                })
                .collect();
            progress.advance(1);
            (row, fallbacks)
        })
        .collect();
    let mut out = TangentMap { tangents: Vec::with_capacity(nx * ny), fallback_texels: 0 };
    for (row, f) in rows {
        out.tangents.extend(row);
        out.fallback_texels += f;
    }
    out
}

/// Principal eigenvector of a symmetric positive semi-definite 3×3 matrix, by repeated
/// squaring (M^(2^10): the second eigenvalue's share falls as (λ2/λ1)^1024); `None` for
/// M ≈ 0. When λ1 = λ2 any unit vector of their plane is returned (deterministically).
pub fn principal_axis(m: Mat3) -> Option<Vec3> {
    let trace = m.x_axis.x + m.y_axis.y + m.z_axis.z;
    if !(trace > 1e-12) || !trace.is_finite() {
        return None;
    }
    let mut a = m * (1.0 / trace);
    for _ in 0..10 {
        a = a * a;
        let t = a.x_axis.x + a.y_axis.y + a.z_axis.z;
        if !(t > 1e-30) {
            return None;
        }
        a *= 1.0 / t;
    }
    // A → e eᵀ (or a projector onto the top eigenspace): its longest column is ∝ e.
    let cols = [a.x_axis, a.y_axis, a.z_axis];
    let best = cols.into_iter().fold(Vec3::ZERO, |b, c| if c.length_squared() > b.length_squared() { c } else { b });
    best.try_normalize()
}

/// The fiber axis `e` projected into the plane ⟂ `n`, unit, with the sign convention;
/// `None` when the axis is (nearly) along the normal.
pub fn tangent_from_axis(e: Vec3, n: Vec3) -> Option<Vec3> {
    let p = e - e.dot(n) * n;
    if !(p.length() >= MIN_PROJECTED) {
        return None;
    }
    Some(oriented(p.normalize()))
}

/// x̂ (or ŷ when n is near x̂) projected into the tangent plane.
pub fn fallback_tangent(n: Vec3) -> Vec3 {
    tangent_from_axis(Vec3::X, n).or_else(|| tangent_from_axis(Vec3::Y, n)).unwrap_or(Vec3::X)
}

/// Applies the sign convention t·(x̂ + ŷ) ≥ 0 (ties: t.x ≥ 0, then t.z ≥ 0).
#[inline]
pub fn oriented(t: Vec3) -> Vec3 {
    let mut s = t.x + t.y;
    if s.abs() < 1e-6 {
        s = t.x;
    }
    if s.abs() < 1e-6 {
        s = t.z;
    }
    if s < 0.0 { -t } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn principal_axis_ignores_the_sign_of_fiber_directions() {
        let w = Vec3::new(0.3, -0.8, 0.2).normalize();
        let mut m = Mat3::ZERO;
        for (s, c) in [(1.0, 1.0), (-1.0, 1.0), (1.0, 0.5)] {
            let v = w * s;
            m += Mat3::from_cols(v * v.x, v * v.y, v * v.z) * c;
        }
        // Plus a weaker second axis.
        let u = Vec3::new(1.0, 0.2, 0.0).normalize();
        m += Mat3::from_cols(u * u.x, u * u.y, u * u.z) * 0.4;
        let e = principal_axis(m).unwrap();
        // The exact top eigenvector is tilted from w by the weak axis; compare with a
        // reference from power iteration in f64.
        let mut r = glam::DVec3::new(1.0, 1.0, 1.0);
        let md = m.as_dmat3();
        for _ in 0..500 {
            r = (md * r).normalize();
        }
        // f32 rounding of M and of the squarings: within 1e-5 rad.
        assert!(e.as_dvec3().angle_between(r).min(e.as_dvec3().angle_between(-r)) < 1e-5, "{e} vs {r}");
        assert_eq!(principal_axis(Mat3::ZERO), None);
    }

    #[test]
    fn sign_convention_keeps_warp_and_weft_stable() {
        // Warp fibers wobbling around ±y all map to +y-ish; weft around ±x to +x-ish.
        for e in [-0.05f32, 0.0, 0.05] {
            assert!(oriented(Vec3::new(e, 1.0, 0.1).normalize()).y > 0.0);
            assert!(oriented(Vec3::new(e, -1.0, 0.1).normalize()).y > 0.0);
            assert!(oriented(Vec3::new(1.0, e, 0.1).normalize()).x > 0.0);
            assert!(oriented(Vec3::new(-1.0, e, 0.1).normalize()).x > 0.0);
        }
        assert_eq!(oriented(Vec3::new(-0.5, 0.5, 0.0)), Vec3::new(0.5, -0.5, 0.0));
        assert_eq!(oriented(-Vec3::Z), Vec3::Z);
    }

    #[test]
    fn tangents_are_unit_orthogonal_and_signed() {
        let n = Vec3::new(0.3, -0.2, 1.0).normalize();
        for e in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::new(-1.0, 1.0, 0.4)] {
            let t = tangent_from_axis(e, n).unwrap();
            assert!((t.length() - 1.0).abs() < 1e-6 && t.dot(n).abs() < 1e-6);
            assert!(t.x + t.y >= 0.0);
            assert!(tangent_from_axis(-e, n).unwrap().abs_diff_eq(t, 1e-6), "sign of ω must not matter");
        }
        assert_eq!(tangent_from_axis(n, n), None);
        let f = fallback_tangent(Vec3::X);
        assert!(f.dot(Vec3::X).abs() < 1e-6 && (f.length() - 1.0).abs() < 1e-6);
    }
}
