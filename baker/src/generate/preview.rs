//! Preview images of a fabric volume seen from above (+z, x to the right, y up: image
//! row 0 is the largest y):
//!
//! - `preview_albedo.png`: the column composited front to back, each voxel with
//!   opacity 1 − exp(−density_scale·ρ·Δz) and its albedo as colour (an unlit look at
//!   what the top of the fabric is made of; flyaways show as translucent strands).
//! - `preview_height.png`: the height where the optical depth from the top reaches 1,
//!   black at the bottom of the volume, white at its top.
//! - `preview_orientation.png`: |ω_f| as RGB at that depth (red: fibers along x,
//!   green: along y, blue: vertical).

use std::path::{Path, PathBuf};

use fabric_runtime::image::{Image, ImageError};
use glam::Vec3;
use rayon::prelude::*;

use crate::volume::FabricVolume;

/// The three previews as linear images.
pub struct Previews {
    pub albedo: Image,
    pub height: Image,
    pub orientation: Image,
}

/// Computes the previews (one column per pixel, in parallel over rows).
pub fn previews(vol: &FabricVolume) -> Previews {
    let [nx, ny, nz] = vol.dims();
    let dz = vol.voxel_size().z;
    let scale = vol.material.density_scale;
    let rows: Vec<Vec<[Vec3; 3]>> = (0..ny)
        .into_par_iter()
        .map(|row| {
            let y = ny - 1 - row;
            (0..nx)
                .map(|x| {
                    let (mut color, mut transmittance, mut depth) = (Vec3::ZERO, 1.0f32, 0.0f32);
                    let (mut height, mut orient) = (0.0f32, Vec3::ZERO);
                    for z in (0..nz).rev() {
                        let v = vol.voxel(x, y, z);
                        if v.is_empty() {
                            continue;
                        }
                        let tau = scale * v.density() * dz;
                        let alpha = 1.0 - (-tau).exp();
                        color += v.albedo() * (transmittance * alpha);
                        transmittance *= 1.0 - alpha;
                        if depth < 1.0 && depth + tau >= 1.0 {
                            height = (z as f32 + 1.0 - (1.0 - depth) / tau) / nz as f32;
                            orient = v.orientation().abs();
                        }
                        depth += tau;
                        if transmittance < 1e-4 && depth >= 1.0 {
                            break;
                        }
                    }
                    [color, Vec3::splat(height.clamp(0.0, 1.0)), orient]
                })
                .collect()
        })
        .collect();
    let image = |k: usize| Image { width: nx as u32, height: ny as u32, pixels: rows.iter().flat_map(|r| r.iter().map(move |p| p[k])).collect() };
    Previews { albedo: image(0), height: image(1), orientation: image(2) }
}

/// Writes `preview_albedo.png`, `preview_height.png` and `preview_orientation.png`
/// into `dir`; returns their paths.
pub fn write_previews(vol: &FabricVolume, dir: &Path) -> Result<Vec<PathBuf>, ImageError> {
    let p = previews(vol);
    let mut out = Vec::new();
    for (name, img) in [("preview_albedo.png", &p.albedo), ("preview_height.png", &p.height), ("preview_orientation.png", &p.orientation)] {
        let path = dir.join(name);
        img.write(&path, 1.0)?;
        out.push(path);
    }
    Ok(out)
}
