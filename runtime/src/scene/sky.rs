//! A built-in procedural sky, so that tests and the demo need no downloaded map: a
//! zenith-to-horizon gradient, a darker ground, a glow around the sun and a sun disk
//! whose total irradiance is exactly `sun_irradiance` (the disk's radiance is that
//! irradiance divided by the disk texels' solid angle, so the piecewise-constant map
//! integrates to it). Deterministic: the same parameters give the same texels.

use std::path::Path;

use glam::Vec3;

use super::envmap::{EnvMap, EnvMapError, EnvMapOptions, local_direction, placed, row_solid_angle};
use super::direction_from_angles;
use crate::image::Image;

/// The sky's parameters (linear RGB radiance, irradiance perpendicular to the sun).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sky {
    /// Unit direction toward the sun.
    pub sun_dir: Vec3,
    /// Irradiance of the whole sun disk.
    pub sun_irradiance: Vec3,
    /// Angular radius of the disk (degrees). The real sun's 0.27° would be a texel or
    /// less; a wider disk keeps the map resolvable.
    pub sun_radius_deg: f32,
    /// Sky radiance straight up and at the horizon.
    pub zenith: Vec3,
    pub horizon: Vec3,
    /// Radiance from below the horizon.
    pub ground: Vec3,
    /// Map size (equirectangular, width = 2 · height is square texels).
    pub width: u32,
    pub height: u32,
}

impl Default for Sky {
    /// A clear afternoon: sun 35° from the zenith, sun irradiance 1 (as the default
    /// directional light), sky about a quarter of it.
    fn default() -> Self {
        Sky {
            sun_dir: direction_from_angles(35.0, -60.0),
            sun_irradiance: Vec3::new(1.0, 0.95, 0.85),
            sun_radius_deg: 2.5,
            zenith: Vec3::new(0.035, 0.06, 0.12),
            horizon: Vec3::new(0.09, 0.1, 0.11),
            ground: Vec3::new(0.02, 0.018, 0.015),
            width: 512,
            height: 256,
        }
    }
}

impl Sky {
    /// The sky as an equirectangular image in the map frame of `EnvMap` (rotation 0).
    pub fn to_image(&self) -> Image {
        let sun = self.sun_dir.normalize_or(Vec3::Z);
        let cos_disk = self.sun_radius_deg.clamp(0.01, 45.0).to_radians().cos();
        let (w, h) = (self.width.max(2), self.height.max(1));
        let centre = |x: u32, y: u32| placed(local_direction((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32), 0.0);
        // Solid angle of the disk as the map sees it: the texels whose centre is inside.
        let mut disk_omega = 0.0f64;
        for y in 0..h {
            let omega = row_solid_angle(y as usize, h as usize, w as usize);
            for x in 0..w {
                if centre(x, y).dot(sun) >= cos_disk {
                    disk_omega += omega;
                }
            }
        }
        let sun_radiance = if disk_omega > 0.0 { self.sun_irradiance / disk_omega as f32 } else { Vec3::ZERO };
        Image::from_fn(w, h, |x, y| {
            let d = centre(x, y);
            if disk_omega > 0.0 && d.dot(sun) >= cos_disk {
                return sun_radiance;
            }
            let up = d.z;
            let sky = if up >= 0.0 {
                let t = (1.0 - up).powi(4);
                self.zenith.lerp(self.horizon, t)
            } else {
                // A soft edge a few degrees below the horizon, then the ground.
                self.horizon.lerp(self.ground, (-up * 12.0).min(1.0))
            };
            let glow = (-(1.0 - d.dot(sun)) * 12.0).exp() * (self.horizon + self.zenith) * 1.5;
            sky + if up > -0.05 { glow } else { Vec3::ZERO }
        })
    }

    /// The sky as an environment map.
    pub fn env_map(&self, options: EnvMapOptions) -> Result<EnvMap, EnvMapError> {
        EnvMap::from_image(&self.to_image(), options, Path::new("built-in sky"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sun_disk_carries_its_irradiance() {
        let sky = Sky { zenith: Vec3::ZERO, horizon: Vec3::ZERO, ground: Vec3::ZERO, ..Sky::default() };
        let map = sky.env_map(EnvMapOptions::default()).unwrap();
        // A black sky except the disk: ∫ L dΩ is the sun's irradiance, from the sun's side.
        assert!((map.integral() - sky.sun_irradiance).abs().max_element() < 1e-4, "{}", map.integral());
        // Every sample lies within the disk.
        for i in 0..100 {
            let s = map.sample((i as f32 + 0.5) / 100.0, ((i * 37) % 100) as f32 / 100.0 + 0.005);
            assert!(s.wi.dot(sky.sun_dir) > (sky.sun_radius_deg + 1.0).to_radians().cos(), "sample {} off the sun", s.wi);
        }
    }

    #[test]
    fn sky_is_brighter_above_than_below() {
        let map = Sky::default().env_map(EnvMapOptions::default()).unwrap();
        let away = -Sky::default().sun_dir;
        let above = map.eval(Vec3::new(away.x, away.y, 0.8).normalize());
        let below = map.eval(Vec3::new(0.3, 0.2, -0.9).normalize());
        assert!(above.min_element() > 1.5 * below.max_element(), "{above} vs {below}");
        assert!(map.eval(Sky::default().sun_dir).x > 100.0 * above.x);
    }
}
