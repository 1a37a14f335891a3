//! PNG previews of an extracted geometry, for a person to check it at a glance. They are
//! data pictures (values mapped linearly to 8 bits, no sRGB curve), not renderings:
//!
//! - `h0.png`, `h.png`: heights, black = min h0, white = max h0 (one scale for both).
//! - `detail.png`: h0 − h, mid-grey = 0, black/white = ∓ its largest magnitude.
//! - `normals.png`, `tangents.png`: (v + 1) / 2 as RGB.
//! - `flyaways.png`: flyaway voxels per column, white = the most.
//! - `autocorrelation.png`: C0 (red, along x) and C1 (blue, along y) over lags 0 … n/2,
//!   the zero line grey, each chosen filter size as a vertical line of its colour
//!   (cf. the paper's Fig. 4).

use std::path::{Path, PathBuf};

use glam::Vec3;
use image::{Rgb, RgbImage};

use super::Geometry;
use super::io::GeometryIoError;

/// Writes all previews into `dir`; returns the paths written.
pub fn write_previews(g: &Geometry, dir: &Path) -> Result<Vec<PathBuf>, GeometryIoError> {
    std::fs::create_dir_all(dir).map_err(|error| GeometryIoError::Io { path: dir.into(), error })?;
    let [nx, ny] = g.dims;
    let [lo, hi] = Geometry::range(&g.h0);
    let span = (hi - lo).max(1e-6);
    let gray = |v: f32| Vec3::splat(((v - lo) / span).clamp(0.0, 1.0));
    let detail: Vec<f32> = g.h0.iter().zip(&g.h).map(|(a, b)| a - b).collect();
    let dmax = detail.iter().fold(1e-6f32, |m, v| m.max(v.abs()));
    let counts: Vec<f32> = (0..nx * ny).map(|c| g.flyaways.column(c % nx, c / nx).len() as f32).collect();
    let cmax = counts.iter().fold(1.0f32, |m, &v| m.max(v));

    type TexelColour<'a> = Box<dyn Fn(usize) -> Vec3 + 'a>;
    let maps: [(&str, TexelColour); 6] = [
        ("h0.png", Box::new(|k| gray(g.h0[k]))),
        ("h.png", Box::new(|k| gray(g.h[k]))),
        ("detail.png", Box::new(|k| Vec3::splat(0.5 + 0.5 * detail[k] / dmax))),
        ("normals.png", Box::new(|k| (g.normals[k] + 1.0) * 0.5)),
        ("tangents.png", Box::new(|k| (g.tangents[k] + 1.0) * 0.5)),
        ("flyaways.png", Box::new(|k| Vec3::splat(counts[k] / cmax))),
    ];
    let mut written = Vec::new();
    for (name, f) in maps.iter() {
        let img = RgbImage::from_fn(nx as u32, ny as u32, |x, y| to_rgb8(f(x as usize + nx * y as usize)));
        written.push(save(&img, &dir.join(name))?);
    }
    written.push(save(&plot_autocorrelation(g), &dir.join("autocorrelation.png"))?);
    Ok(written)
}

fn to_rgb8(v: Vec3) -> Rgb<u8> {
    let q = |c: f32| (if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 } * 255.0).round() as u8;
    Rgb([q(v.x), q(v.y), q(v.z)])
}

fn save(img: &RgbImage, path: &Path) -> Result<PathBuf, GeometryIoError> {
    fabric_runtime::image::write_png_rgb8(path, img.as_raw(), img.width(), img.height())?;
    Ok(path.into())
}

/// C0 and C1 against the lag, with the filter sizes marked.
fn plot_autocorrelation(g: &Geometry) -> RgbImage {
    const W: u32 = 640;
    const H: u32 = 320;
    const MARGIN: f32 = 10.0;
    let mut img = RgbImage::from_pixel(W, H, Rgb([255, 255, 255]));
    let max_lag = (g.dims[0].max(g.dims[1]) / 2).max(1) as f32;
    let px = |lag: f32| MARGIN + lag / max_lag * (W as f32 - 2.0 * MARGIN);
    let py = |c: f32| MARGIN + (1.0 - c.clamp(-1.0, 1.0)) * 0.5 * (H as f32 - 2.0 * MARGIN);
    line(&mut img, (px(0.0), py(0.0)), (px(max_lag), py(0.0)), Rgb([170, 170, 170]));
    let colours = [Rgb([220, 40, 40]), Rgb([40, 80, 220])];
    for (axis, c) in g.autocorrelation.iter().enumerate() {
        let half = c.len() / 2;
        for lag in 0..half {
            line(&mut img, (px(lag as f32), py(c[lag])), (px(lag as f32 + 1.0), py(c[lag + 1])), colours[axis]);
        }
        let s = g.filter_size[axis];
        if s > 0.0 && s <= max_lag {
            // Dashed vertical line at the filter size.
            let mut y = MARGIN;
            while y < H as f32 - MARGIN {
                line(&mut img, (px(s), y), (px(s), y + 4.0), colours[axis]);
                y += 8.0;
            }
        }
    }
    img
}

/// A 1-pixel line by uniform sampling along its longer extent.
fn line(img: &mut RgbImage, a: (f32, f32), b: (f32, f32), c: Rgb<u8>) {
    let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as u32;
    for s in 0..=steps {
        let t = s as f32 / steps as f32;
        let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
        if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
            img.put_pixel(x as u32, y as u32, c);
        }
    }
}
