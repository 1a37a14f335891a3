//! The in-memory fabric volume: density ρ, albedo α (RGB) and fiber orientation ω_f on
//! one cell-centred grid inside a world bounding box (docs/DESIGN.md §3).
//!
//! Layout: one packed 12-byte [`Voxel`] per cell, x fastest, then y, then z (the `.vol`
//! order). A 1024×1024×128 fabric takes 1.6 GiB instead of the 3.5 GiB of f32 channels.
//! What the packing loses:
//! - density as IEEE half: relative error ≤ 2⁻¹¹ (0.05%) for ρ in [6e-5, 65504];
//!   smaller positive values flush toward the half subnormals (absolute error ≤ 3e-8);
//!   values above 65504 are rejected on input, never clamped silently;
//! - albedo as 16-bit unorm per channel: absolute error ≤ 7.7e-6 (albedo must be in
//!   [0, 1]);
//! - orientation as a 2×16-bit octahedral code: angular error ≤ 0.0008 rad (0.05°). The sign
//!   of ω_f is irrelevant (±ω_f is one fiber); decoding returns a unit vector.

use glam::Vec3;

pub use fabric_runtime::scene::Aabb;

/// One voxel, packed. Use the accessors; the fields are codes, not values.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Voxel {
    /// IEEE binary16 bits of ρ.
    pub density: u16,
    /// Albedo, 16-bit unorm per channel.
    pub albedo: [u16; 3],
    /// Octahedral code of ω_f, 16-bit unorm per coordinate.
    pub orientation: [u16; 2],
}

const _: () = assert!(core::mem::size_of::<Voxel>() == 12);

/// Largest density a voxel can hold (the largest finite half).
pub const MAX_DENSITY: f32 = 65504.0;

impl Voxel {
    pub const EMPTY: Voxel = Voxel { density: 0, albedo: [0; 3], orientation: [0; 2] };

    /// Packs a voxel. Inputs are assumed valid (ρ finite in [0, MAX_DENSITY], albedo in
    /// [0, 1], ω_f non-zero); out-of-range values are clamped, NaN becomes 0.
    /// Readers validate before they pack, so nothing is clamped silently there.
    pub fn pack(density: f32, albedo: Vec3, orientation: Vec3) -> Voxel {
        let d = if density.is_nan() { 0.0 } else { density.clamp(0.0, MAX_DENSITY) };
        Voxel { density: half::f16::from_f32(d).to_bits(), albedo: albedo.to_array().map(unorm16), orientation: octahedral_encode(orientation) }
    }

    #[inline]
    pub fn density(&self) -> f32 {
        half::f16::from_bits(self.density).to_f32()
    }

    #[inline]
    pub fn albedo(&self) -> Vec3 {
        Vec3::new(unorm16_to_f32(self.albedo[0]), unorm16_to_f32(self.albedo[1]), unorm16_to_f32(self.albedo[2]))
    }

    /// Unit fiber direction (sign arbitrary).
    #[inline]
    pub fn orientation(&self) -> Vec3 {
        octahedral_decode(self.orientation)
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.density & 0x7fff == 0
    }
}

#[inline]
fn unorm16(v: f32) -> u16 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v * 65535.0 + 0.5) as u16
}

#[inline]
fn unorm16_to_f32(v: u16) -> f32 {
    v as f32 * (1.0 / 65535.0)
}

/// Octahedral map of a direction to two 16-bit codes (Meyer et al. 2010). ±ω encode to
/// different codes; callers treat the decoded direction as an axis.
pub fn octahedral_encode(w: Vec3) -> [u16; 2] {
    let l1 = w.x.abs() + w.y.abs() + w.z.abs();
    if l1.is_nan() || l1 <= 0.0 || !l1.is_finite() {
        return [unorm16(0.5), unorm16(0.5)]; // +Z: a valid unit vector, never NaN
    }
    let p = w / l1;
    let (mut u, mut v) = (p.x, p.y);
    if p.z < 0.0 {
        let (ou, ov) = (u, v);
        u = (1.0 - ov.abs()) * ou.signum();
        v = (1.0 - ou.abs()) * ov.signum();
    }
    [unorm16(u * 0.5 + 0.5), unorm16(v * 0.5 + 0.5)]
}

pub fn octahedral_decode(c: [u16; 2]) -> Vec3 {
    let u = unorm16_to_f32(c[0]) * 2.0 - 1.0;
    let v = unorm16_to_f32(c[1]) * 2.0 - 1.0;
    let z = 1.0 - u.abs() - v.abs();
    let (x, y) = if z < 0.0 { ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum()) } else { (u, v) };
    Vec3::new(x, y, z).normalize()
}

/// Material constants that are not per voxel (DESIGN.md §3, `material.toml`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialParams {
    /// σ_t = density_scale · ρ · σ(ω), per world unit.
    pub density_scale: f32,
    /// SGGX fiber roughness σ in (0, 1]: S = σ²·ω_f ω_fᵀ + (I − ω_f ω_fᵀ).
    pub roughness: f32,
}

impl Default for MaterialParams {
    fn default() -> Self {
        MaterialParams { density_scale: 1.0, roughness: 0.1 }
    }
}

/// Empty voxels for `dims`, or a message saying how much memory the system refused.
pub fn try_voxels(dims: [usize; 3]) -> Result<Vec<Voxel>, String> {
    let n = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d)).ok_or_else(|| format!("{dims:?} voxels overflow the address space"))?;
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| format!("cannot allocate {:.1} GiB for {}x{}x{} voxels ({} bytes each): not enough memory", n as f64 * core::mem::size_of::<Voxel>() as f64 / (1u64 << 30) as f64, dims[0], dims[1], dims[2], core::mem::size_of::<Voxel>()))?;
    v.resize(n, Voxel::EMPTY);
    Ok(v)
}

/// A fabric volume: `dims` = (xres, yres, zres) cells spanning `bbox`, cell-centred.
/// Z+ is up; z = zres is the front surface. The sample tiles periodically in x and y.
#[derive(Clone, Debug, PartialEq)]
pub struct FabricVolume {
    dims: [usize; 3],
    bbox: Aabb,
    voxels: Vec<Voxel>,
    pub material: MaterialParams,
}

impl FabricVolume {
    /// An empty volume. The caller guarantees non-zero dims and a valid box (readers
    /// and the generator check; see `volume::fabric_dir` for the user-facing errors).
    pub fn new(dims: [usize; 3], bbox: Aabb, material: MaterialParams) -> FabricVolume {
        let n = dims[0] * dims[1] * dims[2];
        FabricVolume { dims, bbox, voxels: vec![Voxel::EMPTY; n], material }
    }

    /// [`FabricVolume::new`], reporting an allocation the system refuses (a 1024³ volume
    /// is 12 GiB of voxels) instead of aborting the process.
    pub fn try_new(dims: [usize; 3], bbox: Aabb, material: MaterialParams) -> Result<FabricVolume, String> {
        Ok(FabricVolume { dims, bbox, voxels: try_voxels(dims)?, material })
    }

    /// Wraps packed voxels (length must be the product of `dims`).
    pub fn from_voxels(dims: [usize; 3], bbox: Aabb, voxels: Vec<Voxel>, material: MaterialParams) -> Option<FabricVolume> {
        (voxels.len() == dims[0] * dims[1] * dims[2]).then_some(FabricVolume { dims, bbox, voxels, material })
    }

    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    pub fn bbox(&self) -> Aabb {
        self.bbox
    }

    /// World size of one cell along x, y, z.
    pub fn voxel_size(&self) -> Vec3 {
        self.bbox.size() / Vec3::new(self.dims[0] as f32, self.dims[1] as f32, self.dims[2] as f32)
    }

    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        debug_assert!(x < self.dims[0] && y < self.dims[1] && z < self.dims[2]);
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    #[inline]
    pub fn voxel(&self, x: usize, y: usize, z: usize) -> &Voxel {
        &self.voxels[self.index(x, y, z)]
    }

    /// The voxel with x and y wrapped periodically (the sample tiles in x and y).
    #[inline]
    pub fn voxel_wrapped(&self, x: i64, y: i64, z: usize) -> &Voxel {
        let xi = x.rem_euclid(self.dims[0] as i64) as usize;
        let yi = y.rem_euclid(self.dims[1] as i64) as usize;
        self.voxel(xi, yi, z)
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, z: usize, v: Voxel) {
        let i = self.index(x, y, z);
        self.voxels[i] = v;
    }

    pub fn voxels(&self) -> &[Voxel] {
        &self.voxels
    }

    pub fn voxels_mut(&mut self) -> &mut [Voxel] {
        &mut self.voxels
    }

    /// One z-slab (all x, y at height z), x fastest.
    pub fn slab(&self, z: usize) -> &[Voxel] {
        let n = self.dims[0] * self.dims[1];
        &self.voxels[z * n..(z + 1) * n]
    }

    /// World position of the centre of cell (x, y, z).
    pub fn cell_center(&self, x: usize, y: usize, z: usize) -> Vec3 {
        self.bbox.min + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * self.voxel_size()
    }

    /// Fraction of cells with ρ > 0.
    pub fn filled_fraction(&self) -> f64 {
        let n = self.voxels.iter().filter(|v| !v.is_empty()).count();
        n as f64 / self.voxels.len().max(1) as f64
    }

    /// Bytes held by the voxel array.
    pub fn memory_bytes(&self) -> usize {
        self.voxels.len() * core::mem::size_of::<Voxel>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refused_allocations_are_errors_not_aborts() {
        assert_eq!(try_voxels([2, 3, 4]).unwrap().len(), 24);
        let e = try_voxels([usize::MAX, 2, 1]).unwrap_err();
        assert!(e.contains("overflow"), "{e}");
        // 2^60 voxels: more bytes than any address space holds.
        let e = try_voxels([1 << 20, 1 << 20, 1 << 20]).unwrap_err();
        assert!(e.contains("cannot allocate") && e.contains("1048576x1048576x1048576"), "{e}");
    }

    #[test]
    fn packing_errors_are_as_documented() {
        let mut worst_angle = 0.0f32;
        let mut state = 12345u64;
        let mut rnd = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        };
        for _ in 0..20000 {
            let w = Vec3::new(rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0);
            if w.length() < 1e-3 {
                continue;
            }
            let w = w.normalize();
            let d = octahedral_decode(octahedral_encode(w));
            assert!((d.length() - 1.0).abs() < 1e-6);
            worst_angle = worst_angle.max(d.dot(w).clamp(-1.0, 1.0).acos());
            let rho = rnd() * 10.0;
            let a = Vec3::new(rnd(), rnd(), rnd());
            let v = Voxel::pack(rho, a, w);
            assert!((v.density() - rho).abs() <= rho * 2f32.powi(-11) + 1e-7);
            assert!((v.albedo() - a).abs().max_element() <= 7.7e-6);
        }
        assert!(worst_angle < 8e-4, "worst octahedral error {worst_angle}");
        // Axes and degenerate input decode to unit vectors.
        for w in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            assert!(octahedral_decode(octahedral_encode(w)).abs_diff_eq(w, 1e-4), "{w}");
        }
        assert!(octahedral_decode(octahedral_encode(Vec3::ZERO)).is_normalized());
        assert!(octahedral_decode(octahedral_encode(Vec3::NAN)).is_normalized());
    }

    #[test]
    fn indexing_is_x_fastest_and_wraps() {
        let mut v = FabricVolume::new([4, 3, 2], Aabb::new(Vec3::ZERO, Vec3::new(4.0, 3.0, 2.0)), MaterialParams::default());
        v.set(1, 2, 1, Voxel::pack(0.5, Vec3::ONE, Vec3::X));
        assert_eq!(v.index(1, 2, 1), 1 + 4 * (2 + 3));
        assert_eq!(v.voxel_wrapped(-3, 5, 1).density(), 0.5);
        assert!(v.cell_center(0, 0, 0).abs_diff_eq(Vec3::splat(0.5), 1e-6));
        assert!((v.filled_fraction() - 1.0 / 24.0).abs() < 1e-12);
    }
}
