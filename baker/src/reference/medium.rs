//! The participating medium of a fabric volume: σ_t, albedo and the SGGX matrix at any
//! point, with Mitsuba 3's conventions so that images can be reproduced there.
//!
//! - σ_t(x, ω) = scale · ρ(x) · σ(ω; S(x)),  σ_s(x, ω) = α(x) · σ_t(x, ω)
//!   (Mitsuba 3 `heterogeneous` medium with a phase function flagged `Microflake`: it
//!   multiplies `scale · sigma_t(x)` by the phase function's `projected_area`).
//! - Voxels are cell-centred in the `.vol` bounding box: voxel (i, j, k) is centred at
//!   min + (i + ½, j + ½, k + ½)·voxel_size (Mitsuba `gridvolume`, `use_grid_bbox`).
//! - `Lookup::Trilinear` (Mitsuba's default `filter_type = "bilinear"`, which is
//!   trilinear in 3D) interpolates ρ, α and S *independently*, each from its own grid;
//!   S (not ρ·S) is interpolated, exactly as Mitsuba's `sggx` plugin evaluates its
//!   6-channel `S` volume. Interpolating S = I − (1 − σ²)·ω_f ω_fᵀ is interpolating the
//!   moment ω_f ω_fᵀ; ω_f itself is never interpolated (it is an axis, ±ω_f alike).
//!   At the grid's faces the lookup clamps to the edge voxels (Mitsuba's `wrap_mode =
//!   "clamp"`), so the outer half-voxel shell has the edge values.
//! - `Lookup::Nearest`: the value of the voxel containing the point.
//! - `periodic`: the sample tiles forever in x and y (an infinite sheet); lookups wrap
//!   in x, y (including the trilinear neighbours across the tile edge). Otherwise the
//!   medium ends at the bounding box (outside it, σ_t = 0), as Mitsuba renders a
//!   `cube` shape holding the medium.
//!
//! Points are given in *grid coordinates*: g = (p − bbox.min) / voxel_size, so voxel
//! (i, j, k) spans [i, i+1) × [j, j+1) × [k, k+1). Distances along rays stay in world
//! units (a ray's grid direction is d / voxel_size), so σ_t is per world unit.

use glam::Vec3;

use super::ReferenceError;
use super::sggx::{FiberMoment, Sggx};
use crate::volume::FabricVolume;

/// How the grid is sampled between voxel centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Lookup {
    /// Trilinear interpolation of ρ, α and S between voxel centres (Mitsuba's default).
    #[default]
    Trilinear,
    /// The voxel containing the point.
    Nearest,
}

/// What the S of an interpolated lookup takes from the voxels it reads (DESIGN.md §4:
/// an empty voxel carries no orientation, so nothing stored in empty space may change
/// an image; real micro-CT volumes store zeros or noise there).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EmptyOrientation {
    /// A voxel with ρ = 0 (empty, or removed by the mask) contributes S = I with its
    /// interpolation weight; the others their fiber S. What Mitsuba renders from an S
    /// grid that holds I in empty voxels.
    #[default]
    Isotropic,
    /// S = Σ wᵢρᵢ Sᵢ / Σ wᵢρᵢ: weighted by density, so that a fiber's S reaches its
    /// edge undiluted (S = I where every voxel read is empty).
    DensityWeighted,
}

/// Options of a medium.
#[derive(Clone, Copy, Debug, Default)]
pub struct MediumOptions<'m> {
    pub lookup: Lookup,
    /// How empty voxels enter the interpolated S.
    pub empty_orientation: EmptyOrientation,
    /// Tile the sample forever in x and y.
    pub periodic: bool,
    /// Voxels to remove from the medium (`true` = removed), one per voxel in volume
    /// order (x fastest). The baker removes the flyaway voxels when it measures the
    /// surface. A removed voxel has ρ = 0 and is empty in every respect: its stored S
    /// is not used (see [`EmptyOrientation`]); its α enters the interpolated albedo but
    /// only ever multiplies an interpolated ρ.
    pub mask: Option<&'m [bool]>,
}

/// The voxels that contribute to a lookup, with their weights (Σ w = 1).
#[derive(Clone, Copy, Debug)]
pub struct Footprint {
    pub index: [usize; 8],
    pub weight: [f32; 8],
    pub count: usize,
}

/// A fabric volume seen as a participating medium.
pub struct Medium<'v> {
    volume: &'v FabricVolume,
    /// ρ per voxel (unscaled), with the mask applied.
    density: Vec<f32>,
    dims: [usize; 3],
    dims_f: Vec3,
    inv_dims_f: Vec3,
    scale: f32,
    roughness: f32,
    /// Upper bound of σ(ω) over ω and over every interpolated S: the largest
    /// eigenvalue of a fiber S is max(1, σ²), and convex combinations keep the bound.
    max_projected_area: f32,
    lookup: Lookup,
    empty_orientation: EmptyOrientation,
    periodic: bool,
}

impl<'v> Medium<'v> {
    pub fn new(volume: &'v FabricVolume, options: MediumOptions<'_>) -> Result<Medium<'v>, ReferenceError> {
        let dims = volume.dims();
        let n = dims[0] * dims[1] * dims[2];
        if n == 0 || !volume.bbox().is_valid() {
            return Err(ReferenceError::BadVolume(format!("dimensions {dims:?}, bounding box {:?}", volume.bbox())));
        }
        let m = volume.material;
        if !(m.density_scale.is_finite() && m.density_scale >= 0.0) {
            return Err(ReferenceError::BadVolume(format!("density scale {} must be finite and non-negative", m.density_scale)));
        }
        if !(m.roughness.is_finite() && m.roughness > 0.0) {
            return Err(ReferenceError::BadVolume(format!("SGGX roughness {} must be finite and positive", m.roughness)));
        }
        if let Some(mask) = options.mask
            && mask.len() != n
        {
            return Err(ReferenceError::MaskLength { expected: n, got: mask.len() });
        }
        let density = match options.mask {
            Some(mask) => volume.voxels().iter().zip(mask).map(|(v, &removed)| if removed { 0.0 } else { v.density() }).collect(),
            None => volume.voxels().iter().map(|v| v.density()).collect(),
        };
        let dims_f = Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32);
        Ok(Medium {
            volume,
            density,
            dims,
            dims_f,
            inv_dims_f: dims_f.recip(),
            scale: m.density_scale,
            roughness: m.roughness,
            max_projected_area: m.roughness.max(1.0),
            lookup: options.lookup,
            empty_orientation: options.empty_orientation,
            periodic: options.periodic,
        })
    }

    pub fn volume(&self) -> &'v FabricVolume {
        self.volume
    }

    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    pub fn dims_f(&self) -> Vec3 {
        self.dims_f
    }

    pub fn is_periodic(&self) -> bool {
        self.periodic
    }

    pub fn lookup(&self) -> Lookup {
        self.lookup
    }

    /// σ_t = scale · ρ · σ(ω): the scale.
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// The bound on σ(ω) used by the majorants.
    pub fn max_projected_area(&self) -> f32 {
        self.max_projected_area
    }

    /// ρ of voxel `i` (volume order), mask applied.
    #[inline]
    pub fn voxel_density(&self, i: usize) -> f32 {
        self.density[i]
    }

    /// World point → grid coordinates.
    #[inline]
    pub fn to_grid(&self, p: Vec3) -> Vec3 {
        (p - self.volume.bbox().min) / self.volume.voxel_size()
    }

    /// Grid coordinates → world point.
    #[inline]
    pub fn to_world(&self, g: Vec3) -> Vec3 {
        self.volume.bbox().min + g * self.volume.voxel_size()
    }

    /// Wraps x and y into the base tile (periodic media only; identity otherwise).
    #[inline]
    pub fn wrap(&self, g: Vec3) -> Vec3 {
        if !self.periodic {
            return g;
        }
        let x = g.x - (g.x * self.inv_dims_f.x).floor() * self.dims_f.x;
        let y = g.y - (g.y * self.inv_dims_f.y).floor() * self.dims_f.y;
        // Rounding can land exactly on the upper edge; that is voxel 0 of the next tile.
        Vec3::new(if x >= self.dims_f.x { 0.0 } else { x }, if y >= self.dims_f.y { 0.0 } else { y }, g.z)
    }

    /// The voxels and weights that the lookup at grid point `g` reads.
    #[inline]
    pub fn footprint(&self, g: Vec3) -> Footprint {
        let g = self.wrap(g);
        let [nx, ny, nz] = self.dims;
        match self.lookup {
            Lookup::Nearest => {
                let ix = self.nearest_axis(g.x, nx, self.periodic);
                let iy = self.nearest_axis(g.y, ny, self.periodic);
                let iz = self.nearest_axis(g.z, nz, false);
                Footprint { index: [ix + nx * (iy + ny * iz), 0, 0, 0, 0, 0, 0, 0], weight: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], count: 1 }
            }
            Lookup::Trilinear => {
                let (x0, x1, fx) = linear_axis(g.x, nx, self.periodic);
                let (y0, y1, fy) = linear_axis(g.y, ny, self.periodic);
                let (z0, z1, fz) = linear_axis(g.z, nz, false);
                let (row0, row1) = (nx * (y0 + ny * z0), nx * (y1 + ny * z0));
                let (row2, row3) = (nx * (y0 + ny * z1), nx * (y1 + ny * z1));
                let (gx, gy, gz) = (1.0 - fx, 1.0 - fy, 1.0 - fz);
                Footprint {
                    index: [row0 + x0, row0 + x1, row1 + x0, row1 + x1, row2 + x0, row2 + x1, row3 + x0, row3 + x1],
                    weight: [gx * gy * gz, fx * gy * gz, gx * fy * gz, fx * fy * gz, gx * gy * fz, fx * gy * fz, gx * fy * fz, fx * fy * fz],
                    count: 8,
                }
            }
        }
    }

    #[inline]
    fn nearest_axis(&self, g: f32, n: usize, periodic: bool) -> usize {
        let i = g.floor() as i64;
        if periodic { i.rem_euclid(n as i64) as usize } else { i.clamp(0, n as i64 - 1) as usize }
    }

    /// ρ (unscaled) over a footprint.
    #[inline]
    pub fn density(&self, f: &Footprint) -> f32 {
        let mut rho = 0.0;
        for k in 0..f.count {
            rho += f.weight[k] * self.density[f.index[k]];
        }
        rho
    }

    /// The interpolated SGGX matrix over a footprint. Empty voxels (ρ = 0 after the
    /// mask) never contribute their stored orientation ([`EmptyOrientation`]).
    #[inline]
    pub fn sggx(&self, f: &Footprint) -> Sggx {
        let voxels = self.volume.voxels();
        let mut m = FiberMoment::default();
        match self.empty_orientation {
            EmptyOrientation::Isotropic => {
                // S = I − (1 − σ²)·Σ wᵢ ω_fᵢ ω_fᵢᵀ over the non-empty voxels: an omitted
                // voxel contributes wᵢ·I, since S is affine in the moment.
                for k in 0..f.count {
                    if f.weight[k] > 0.0 && self.density[f.index[k]] > 0.0 {
                        m.add_weighted(voxels[f.index[k]].orientation(), f.weight[k]);
                    }
                }
            }
            EmptyOrientation::DensityWeighted => {
                let mut total = 0.0;
                for k in 0..f.count {
                    let w = f.weight[k] * self.density[f.index[k]];
                    if w > 0.0 {
                        m.add_weighted(voxels[f.index[k]].orientation(), w);
                        total += w;
                    }
                }
                if total > 0.0 {
                    let inv = 1.0 / total;
                    m = FiberMoment { xx: m.xx * inv, yy: m.yy * inv, zz: m.zz * inv, xy: m.xy * inv, xz: m.xz * inv, yz: m.yz * inv };
                }
            }
        }
        Sggx::from_fiber_moment(m, self.roughness)
    }

    /// The interpolated single-scattering albedo over a footprint.
    #[inline]
    pub fn albedo(&self, f: &Footprint) -> Vec3 {
        let voxels = self.volume.voxels();
        let mut a = Vec3::ZERO;
        for k in 0..f.count {
            if f.weight[k] > 0.0 {
                a += f.weight[k] * voxels[f.index[k]].albedo();
            }
        }
        a
    }

    /// σ_t(g, ω) per world unit.
    pub fn sigma_t(&self, g: Vec3, w: Vec3) -> f32 {
        let f = self.footprint(g);
        let rho = self.density(&f);
        if rho <= 0.0 {
            return 0.0;
        }
        self.scale * rho * self.sggx(&f).projected_area(w)
    }

    /// Whether grid point `g` lies inside the medium's support (the z range of the
    /// slab; x and y too unless periodic).
    #[inline]
    pub fn contains(&self, g: Vec3) -> bool {
        let in_z = g.z >= 0.0 && g.z <= self.dims_f.z;
        in_z && (self.periodic || (g.x >= 0.0 && g.x <= self.dims_f.x && g.y >= 0.0 && g.y <= self.dims_f.y))
    }

    /// The parametric interval [t0, t1] (world units, t ≥ `t_min`) in which the ray
    /// `g0 + t·dg` (grid coordinates) is inside the slab, or `None`.
    pub fn clip(&self, g0: Vec3, dg: Vec3, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let (mut t0, mut t1) = (t_min, t_max);
        let axes = if self.periodic { 2..3 } else { 0..3 };
        for a in axes {
            let (o, d, hi) = (g0[a], dg[a], self.dims_f[a]);
            if d == 0.0 {
                if o < 0.0 || o > hi {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d;
            let (mut ta, mut tb) = ((0.0 - o) * inv, (hi - o) * inv);
            if ta > tb {
                core::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        (t0 < t1).then_some((t0, t1))
    }
}

/// Trilinear neighbours along one axis: voxel centres at i + ½, clamped at the faces
/// (non-periodic) or wrapped (periodic; `g` already in [0, n)).
#[inline]
fn linear_axis(g: f32, n: usize, periodic: bool) -> (usize, usize, f32) {
    let x = g - 0.5;
    let fl = x.floor();
    let frac = x - fl;
    let i = fl as i64;
    let n = n as i64;
    if periodic {
        let i0 = if i < 0 { i + n } else if i >= n { i - n } else { i };
        let i1 = if i0 + 1 >= n { i0 + 1 - n } else { i0 + 1 };
        (i0 as usize, i1 as usize, frac)
    } else {
        ((i.clamp(0, n - 1)) as usize, ((i + 1).clamp(0, n - 1)) as usize, frac)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Aabb, MaterialParams, Voxel};

    fn volume() -> FabricVolume {
        let mut v = FabricVolume::new([4, 3, 2], Aabb::new(Vec3::ZERO, Vec3::new(4.0, 3.0, 1.0)), MaterialParams { density_scale: 2.0, roughness: 0.5 });
        for z in 0..2 {
            for y in 0..3 {
                for x in 0..4 {
                    let rho = (1 + x + 4 * y + 12 * z) as f32;
                    let dir = if x % 2 == 0 { Vec3::X } else { Vec3::Y };
                    v.set(x, y, z, Voxel::pack(rho, Vec3::splat(0.25 * (x as f32)), dir));
                }
            }
        }
        v
    }

    #[test]
    fn trilinear_is_cell_centred_and_clamps_or_wraps() {
        let v = volume();
        let m = Medium::new(&v, MediumOptions::default()).unwrap();
        // At a voxel centre the lookup returns that voxel.
        let f = m.footprint(Vec3::new(1.5, 2.5, 0.5));
        assert_eq!(m.density(&f), v.voxel(1, 2, 0).density());
        // Half way between x = 1 and x = 2 centres.
        let f = m.footprint(Vec3::new(2.0, 0.5, 0.5));
        assert!((m.density(&f) - 2.5).abs() < 1e-6);
        // S is interpolated: half X-fiber, half Y-fiber → S_xx = S_yy = 1 − 0.75·0.5.
        let s = m.sggx(&f);
        assert!((s.xx - 0.625).abs() < 1e-3 && (s.yy - 0.625).abs() < 1e-3 && (s.zz - 1.0).abs() < 1e-3, "{s:?}");
        // The outer half-voxel clamps to the edge voxel.
        assert_eq!(m.density(&m.footprint(Vec3::new(0.1, 0.2, 0.1))), 1.0);
        // Periodic: x = 0.1 blends voxel 0 (weight 0.6) with voxel 3 (weight 0.4).
        let p = Medium::new(&v, MediumOptions { periodic: true, ..Default::default() }).unwrap();
        let d = p.density(&p.footprint(Vec3::new(0.1, 0.5, 0.5)));
        assert!((d - (0.6 * 1.0 + 0.4 * 4.0)).abs() < 1e-5, "{d}");
        // ... and a point one tile over reads the same.
        assert!((p.density(&p.footprint(Vec3::new(-3.9, 3.5, 0.5))) - d).abs() < 1e-5);
        // σ_t = scale · ρ · σ(ω): along +Z every fiber here has σ = 1.
        assert!((m.sigma_t(Vec3::new(1.5, 2.5, 0.5), Vec3::Z) - 2.0 * 10.0).abs() < 1e-4);
    }

    #[test]
    fn nearest_reads_the_containing_voxel() {
        let v = volume();
        let m = Medium::new(&v, MediumOptions { lookup: Lookup::Nearest, ..Default::default() }).unwrap();
        assert_eq!(m.density(&m.footprint(Vec3::new(1.99, 0.01, 1.5))), v.voxel(1, 0, 1).density());
        assert_eq!(m.albedo(&m.footprint(Vec3::new(3.5, 2.5, 0.5))), v.voxel(3, 2, 0).albedo());
    }

    #[test]
    fn mask_removes_voxels_and_bad_masks_are_rejected() {
        let v = volume();
        let mut mask = vec![false; 24];
        mask[v.index(1, 2, 0)] = true;
        let m = Medium::new(&v, MediumOptions { mask: Some(&mask), lookup: Lookup::Nearest, ..Default::default() }).unwrap();
        assert_eq!(m.density(&m.footprint(Vec3::new(1.5, 2.5, 0.5))), 0.0);
        assert_eq!(m.density(&m.footprint(Vec3::new(2.5, 2.5, 0.5))), v.voxel(2, 2, 0).density());
        assert!(matches!(Medium::new(&v, MediumOptions { mask: Some(&mask[..5]), ..Default::default() }), Err(ReferenceError::MaskLength { expected: 24, got: 5 })));
    }

    #[test]
    fn clipping_to_the_slab() {
        let v = volume();
        let m = Medium::new(&v, MediumOptions::default()).unwrap();
        // Straight down through the middle: z from 2 to 0 in grid units, world t = 0..1
        // (voxel z size 0.5, so dg.z = −2 per world unit).
        let (t0, t1) = m.clip(Vec3::new(2.0, 1.5, 4.0), Vec3::new(0.0, 0.0, -2.0), 0.0, f32::INFINITY).unwrap();
        assert!((t0 - 1.0).abs() < 1e-6 && (t1 - 2.0).abs() < 1e-6);
        // Outside in x: missed unless periodic.
        assert!(m.clip(Vec3::new(9.0, 1.5, 4.0), Vec3::new(0.0, 0.0, -2.0), 0.0, f32::INFINITY).is_none());
        let p = Medium::new(&v, MediumOptions { periodic: true, ..Default::default() }).unwrap();
        assert!(p.clip(Vec3::new(9.0, 1.5, 4.0), Vec3::new(0.0, 0.0, -2.0), 0.0, f32::INFINITY).is_some());
        // Horizontal ray inside a periodic slab never leaves it.
        assert_eq!(p.clip(Vec3::new(1.0, 1.0, 1.0), Vec3::X, 0.0, f32::INFINITY), Some((0.0, f32::INFINITY)));
    }
    /// A volume whose every other voxel is empty, with `dir(x, y, z)` stored in the
    /// empty ones (what a micro-CT volume holds there is arbitrary).
    fn sparse_volume(dir: impl Fn(usize, usize, usize) -> Vec3) -> FabricVolume {
        let mut v = FabricVolume::new([6, 5, 4], Aabb::new(Vec3::ZERO, Vec3::new(6.0, 5.0, 4.0)), MaterialParams { density_scale: 3.0, roughness: 0.3 });
        for z in 0..4 {
            for y in 0..5 {
                for x in 0..6 {
                    let filled = (x + 2 * y + 3 * z) % 3 != 0;
                    let voxel = if filled { Voxel::pack(1.0 + x as f32, Vec3::splat(0.8), Vec3::new(1.0, 0.3 * y as f32, 0.1)) } else { Voxel::pack(0.0, Vec3::splat(0.8), dir(x, y, z)) };
                    v.set(x, y, z, voxel);
                }
            }
        }
        v
    }

    #[test]
    fn what_empty_voxels_store_never_changes_the_medium() {
        let a = sparse_volume(|_, _, _| Vec3::Z);
        let b = sparse_volume(|x, y, z| {
            let h = crate::reference::rng::mix64((x + 7 * y + 49 * z) as u64);
            Vec3::new((h & 0xff) as f32 - 127.5, ((h >> 8) & 0xff) as f32 - 127.5, ((h >> 16) & 0xff) as f32 - 127.5)
        });
        for empty_orientation in [EmptyOrientation::Isotropic, EmptyOrientation::DensityWeighted] {
            let options = MediumOptions { periodic: true, empty_orientation, ..Default::default() };
            let (ma, mb) = (Medium::new(&a, options).unwrap(), Medium::new(&b, options).unwrap());
            for k in 0..2000 {
                let g = Vec3::new((k % 37) as f32 * 0.17, (k % 23) as f32 * 0.23, (k % 13) as f32 * 0.31);
                let (fa, fb) = (ma.footprint(g), mb.footprint(g));
                assert_eq!(ma.sggx(&fa).to_array(), mb.sggx(&fb).to_array(), "{empty_orientation:?} at {g}");
            }
        }
        // Isotropic: between a filled X-ish fiber voxel and an empty one, S is half fiber,
        // half I; density-weighted: the fiber's S undiluted.
        let iso = Medium::new(&a, MediumOptions::default()).unwrap();
        let dw = Medium::new(&a, MediumOptions { empty_orientation: EmptyOrientation::DensityWeighted, ..Default::default() }).unwrap();
        // Voxel (0,0,0) is empty, (1,0,0) filled; half way between their centres.
        let g = Vec3::new(1.0, 0.5, 0.5);
        let fiber = Sggx::fiber(Vec3::new(1.0, 0.0, 0.1).normalize(), 0.3);
        let (si, sd) = (iso.sggx(&iso.footprint(g)), dw.sggx(&dw.footprint(g)));
        assert!((si.xx - 0.5 * (1.0 + fiber.xx)).abs() < 1e-3, "{si:?} vs {fiber:?}");
        assert!((sd.xx - fiber.xx).abs() < 1e-3, "{sd:?} vs {fiber:?}");
        // And so the images: bit-identical measurement images.
        let b = sparse_volume(|x, y, z| Vec3::new(y as f32 + 0.5, z as f32 - 1.5, x as f32 * 0.3 + 0.2));
        let (wi, wo) = (Vec3::new(0.5, 0.2, 0.8), Vec3::new(-0.4, 0.1, 0.9));
        let image = |v: &FabricVolume| crate::reference::MeasureScene::new(v, Lookup::Trilinear, None, None).unwrap().render_image(wi, wo, 8, 3).unwrap().0;
        let (ia, ib) = (image(&a), image(&b));
        assert!(ia.mean() > 0.0);
        assert_eq!(ia.pixels, ib.pixels);
    }
}
