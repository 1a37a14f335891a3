//! Reading the fabric directory for the rendering commands.
//!
//! TEMPORARY: a minimal reader of f32 `.vol` files (density, albedo, orientation) and
//! the two keys of `material.toml`, until `fabric_baker::volume::load_fabric` (the
//! volumes engineer's validated loader) lands on main; then `load` becomes a call to it.

use std::path::Path;

use anyhow::{Context, Result, bail};
use fabric_baker::volume::{Aabb, FabricVolume, MaterialParams, Voxel};
use glam::Vec3;

struct Grid {
    dims: [usize; 3],
    channels: usize,
    bbox: Aabb,
    data: Vec<f32>,
}

fn read_vol(path: &Path, channels: usize) -> Result<Grid> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    if bytes.len() < 48 || &bytes[0..3] != b"VOL" || bytes[3] != 3 {
        bail!("{}: not a Mitsuba .vol file (bad magic or version)", path.display());
    }
    let i32_at = |o: usize| i32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
    let f32_at = |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
    if i32_at(4) != 1 {
        bail!("{}: encoding {} not supported here (f32 = 1 only)", path.display(), i32_at(4));
    }
    let d = [i32_at(8), i32_at(12), i32_at(16)];
    if d.iter().any(|&v| !(1..=65536).contains(&v)) {
        bail!("{}: bad dimensions {:?}", path.display(), d);
    }
    let c = i32_at(20) as usize;
    if c != channels {
        bail!("{}: {} channels, expected {}", path.display(), c, channels);
    }
    let dims = [d[0] as usize, d[1] as usize, d[2] as usize];
    let bbox = Aabb::new(Vec3::new(f32_at(24), f32_at(28), f32_at(32)), Vec3::new(f32_at(36), f32_at(40), f32_at(44)));
    let n = dims[0] * dims[1] * dims[2] * c;
    if bytes.len() != 48 + 4 * n {
        bail!("{}: {} bytes, expected {}", path.display(), bytes.len(), 48 + 4 * n);
    }
    let data = bytes[48..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    Ok(Grid { dims, channels: c, bbox, data })
}

fn read_material(path: &Path) -> Result<MaterialParams> {
    let mut m = MaterialParams::default();
    let Ok(text) = std::fs::read_to_string(path) else { return Ok(m) };
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.starts_with('[') {
            break;
        }
        if let Some((k, v)) = line.split_once('=') {
            let v: f32 = v.trim().parse().with_context(|| format!("{}: bad value in '{line}'", path.display()))?;
            match k.trim() {
                "density_scale" => m.density_scale = v,
                "roughness" => m.roughness = v,
                other => bail!("{}: unknown key '{other}'", path.display()),
            }
        }
    }
    Ok(m)
}

/// Loads `dir`; `density_scale` / `roughness` override material.toml.
pub fn load(dir: &Path, density_scale: Option<f32>, roughness: Option<f32>) -> Result<FabricVolume> {
    let rho = read_vol(&dir.join("density.vol"), 1)?;
    let alb = read_vol(&dir.join("albedo.vol"), 3)?;
    let ori = read_vol(&dir.join("orientation.vol"), 3)?;
    for g in [&alb, &ori] {
        if g.dims != rho.dims || g.bbox != rho.bbox {
            bail!("{}: grids differ in size or bounding box", dir.display());
        }
    }
    if !rho.bbox.is_valid() {
        bail!("{}: invalid bounding box {:?}", dir.display(), rho.bbox);
    }
    let mut m = read_material(&dir.join("material.toml"))?;
    m.density_scale = density_scale.unwrap_or(m.density_scale);
    m.roughness = roughness.unwrap_or(m.roughness);
    let n = rho.dims[0] * rho.dims[1] * rho.dims[2];
    let mut voxels = Vec::with_capacity(n);
    for i in 0..n {
        let d = rho.data[i * rho.channels];
        if !d.is_finite() || d < 0.0 {
            bail!("{}: density {} at voxel {}", dir.display(), d, i);
        }
        let a = Vec3::from_slice(&alb.data[3 * i..3 * i + 3]);
        let o = Vec3::from_slice(&ori.data[3 * i..3 * i + 3]);
        voxels.push(Voxel::pack(d, a, o));
    }
    FabricVolume::from_voxels(rho.dims, rho.bbox, voxels, m).context("voxel count mismatch")
}
