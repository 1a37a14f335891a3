//! The image loop: one path per sample through each pixel, rows in parallel (rayon),
//! a progress bar, paths per second.
//!
//! Determinism: pixel (c, r)'s sample s uses the random stream (seed, r·width + c, s)
//! and is summed in sample order in f64, so the image is bit-identical for any number
//! of threads. The box pixel filter (uniform jitter over the pixel) matches Mitsuba 3
//! with `rfilter = box`.

use std::time::Instant;

use fabric_runtime::image::Image;
use fabric_runtime::scene::Camera;
use glam::{DVec3, Vec3};
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::ReferenceError;
use super::integrator::{Lighting, PathSettings, PathStats, radiance};
use super::rng::Rng;
use super::tracking::TracedMedium;

/// What to render.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    pub spp: u32,
    pub seed: u64,
    pub path: PathSettings,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings { spp: 64, seed: 0, path: PathSettings::default() }
    }
}

/// Counters and wall time of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    pub paths: PathStats,
    pub seconds: f64,
}

impl RenderStats {
    pub fn paths_per_second(&self) -> f64 {
        self.paths.paths as f64 / self.seconds.max(1e-9)
    }
}

impl RenderSettings {
    pub fn validate(&self) -> Result<(), ReferenceError> {
        if self.spp == 0 {
            return Err(ReferenceError::ZeroSamples);
        }
        if self.path.max_depth == Some(0) {
            return Err(ReferenceError::ZeroDepth);
        }
        Ok(())
    }
}

/// Renders the medium through `camera` under `lighting` (`(&light).into()` for one light). `progress` (if any) advances by
/// one per finished row.
pub fn render(medium: &TracedMedium<'_>, camera: &Camera, lighting: &Lighting<'_>, settings: &RenderSettings, progress: Option<&ProgressBar>) -> Result<(Image, RenderStats), ReferenceError> {
    settings.validate()?;
    camera.validate()?;
    if let Some(light) = lighting.light {
        light.validate()?;
    }
    let start = Instant::now();
    let (w, h) = (camera.width, camera.height);
    let rows: Vec<(Vec<Vec3>, PathStats)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut stats = PathStats::default();
            let row = (0..w)
                .map(|x| {
                    let pixel = y as u64 * w as u64 + x as u64;
                    let mut sum = DVec3::ZERO;
                    for s in 0..settings.spp {
                        let mut rng = Rng::new(settings.seed, pixel, s as u64);
                        let (jx, jy) = rng.next_2d();
                        let ray = camera.ray(x as f32 + jx, y as f32 + jy);
                        sum += radiance(medium, lighting, &settings.path, ray.o, ray.d, &mut rng, &mut stats).as_dvec3();
                    }
                    (sum / settings.spp as f64).as_vec3()
                })
                .collect();
            if let Some(p) = progress {
                p.inc(1);
            }
            (row, stats)
        })
        .collect();
    let mut image = Image::new(w, h);
    let mut stats = RenderStats::default();
    for (y, (row, s)) in rows.into_iter().enumerate() {
        image.pixels[y * w as usize..(y + 1) * w as usize].copy_from_slice(&row);
        stats.paths.add(&s);
    }
    stats.seconds = start.elapsed().as_secs_f64();
    Ok((image, stats))
}
