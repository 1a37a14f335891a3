//! Compact bright sources (a sun, a lamp) taken out of an environment map as
//! directional lights, so that the renderers shade them exactly (with height-field
//! shadows) and prefilter only the smooth remainder, which SG lookups blur well.
//!
//! Repeatedly, up to `max_lights` times: the brightest remaining texel (luminance Y) is
//! a source if it is at least `contrast` times the mean of the ring 8°–12° around it
//! (the local background). Its region is the texels within 8° brighter than
//! 10% of its peak; each gives up what exceeds the background (per channel), so the
//! remainder is continuous across the region's edge. The light's irradiance is the
//! sum of L − background over the region's solid angle, its direction the
//! power-weighted mean direction. Where the ring holds no texel centre (a map of a few
//! texels) there is no background to tell a compact source from, and no source is
//! taken: a 2×1 constant map, whose two texels were once taken out as lights on the
//! horizon, drew black. A source is kept only if it carries at least `min_fraction` of
//! the map's power. The map with the sources removed plus the lights
//! integrate to the original map exactly (per channel, ∫ L dΩ), which the test checks.

use glam::Vec3;

use super::envmap::{EnvMap, EnvMapError, row_solid_angle};
use super::light::Light;

/// How sources are found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExtractOptions {
    pub max_lights: usize,
    pub contrast: f32,
    pub min_fraction: f32,
}

impl Default for ExtractOptions {
    fn default() -> Self {
        ExtractOptions { max_lights: 4, contrast: 20.0, min_fraction: 0.02 }
    }
}

const REGION_DEG: f32 = 8.0;
const RING_DEG: f32 = 12.0;

fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The sources of `map` as directional lights, and the map without them.
pub fn extract_lights(map: &EnvMap, options: ExtractOptions) -> Result<(Vec<Light>, EnvMap), EnvMapError> {
    let (w, h) = (map.width() as usize, map.height() as usize);
    let mut texels: Vec<Vec3> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| map.texel(x as u32, y as u32)).collect();
    let dirs: Vec<Vec3> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| map.direction((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32)).collect();
    let omega: Vec<f32> = (0..h).map(|y| row_solid_angle(y, h, w) as f32).collect();
    let total: f32 = texels.iter().enumerate().map(|(i, t)| luminance(*t) * omega[i / w]).sum();
    let (cos_region, cos_ring) = (REGION_DEG.to_radians().cos(), RING_DEG.to_radians().cos());
    let mut lights = Vec::new();
    if !(total > 0.0) {
        return Ok((lights, map.clone()));
    }
    for _ in 0..options.max_lights {
        let Some((peak, peak_y)) = texels.iter().enumerate().map(|(i, t)| (i, luminance(*t))).max_by(|a, b| a.1.total_cmp(&b.1)) else { break };
        let centre = dirs[peak];
        let (mut ring, mut ring_omega) = (Vec3::ZERO, 0.0f32);
        for (i, d) in dirs.iter().enumerate() {
            let c = d.dot(centre);
            if c < cos_region && c >= cos_ring {
                ring += texels[i] * omega[i / w];
                ring_omega += omega[i / w];
            }
        }
        if !(ring_omega > 0.0) {
            break;
        }
        let background = ring / ring_omega;
        if !(peak_y > options.contrast * luminance(background)) || !(peak_y > 0.0) {
            break;
        }
        let (mut irradiance, mut axis) = (Vec3::ZERO, Vec3::ZERO);
        let mut removed = Vec::new();
        for (i, d) in dirs.iter().enumerate() {
            if d.dot(centre) >= cos_region && luminance(texels[i]) >= 0.1 * peak_y {
                let excess = (texels[i] - background).max(Vec3::ZERO);
                let e = excess * omega[i / w];
                irradiance += e;
                axis += *d * luminance(e);
                removed.push((i, texels[i] - excess));
            }
        }
        if !(luminance(irradiance) >= options.min_fraction * total) {
            break;
        }
        for (i, rest) in removed {
            texels[i] = rest;
        }
        lights.push(Light::directional(axis.normalize_or(centre), irradiance));
    }
    Ok((lights, map.with_texels(texels)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{EnvMapOptions, Sky};

    #[test]
    fn the_sun_becomes_a_light_and_power_is_conserved() {
        let sky = Sky::default();
        let map = sky.env_map(EnvMapOptions { scale: 1.5, rotate_deg: 0.0 }).unwrap();
        let (lights, rest) = extract_lights(&map, ExtractOptions::default()).unwrap();
        assert_eq!(lights.len(), 1, "{lights:?}");
        let Light::Directional { dir_to_light, irradiance } = lights[0] else { panic!() };
        assert!(dir_to_light.dot(sky.sun_dir) > 0.5f32.to_radians().cos(), "{dir_to_light} vs {}", sky.sun_dir);
        // The disk's irradiance (×1.5), less the background under it.
        assert!((irradiance.x / (1.5 * sky.sun_irradiance.x) - 1.0).abs() < 0.02, "{irradiance}");
        let sum = rest.integral() + irradiance;
        assert!((sum - map.integral()).abs().max_element() < 1e-3 * map.integral().max_element(), "{sum} vs {}", map.integral());
        assert!(rest.eval(sky.sun_dir).x < 2.0, "the sun is gone from the remainder");
    }

    #[test]
    fn smooth_maps_give_no_lights() {
        let map = Sky { sun_irradiance: Vec3::ZERO, ..Sky::default() }.env_map(EnvMapOptions::default()).unwrap();
        assert!(extract_lights(&map, ExtractOptions::default()).unwrap().0.is_empty());
        assert!(extract_lights(&EnvMap::constant(Vec3::ONE).unwrap(), ExtractOptions::default()).unwrap().0.is_empty());
        assert!(extract_lights(&EnvMap::constant(Vec3::ZERO).unwrap(), ExtractOptions::default()).unwrap().0.is_empty());
    }

    #[test]
    fn maps_too_coarse_to_hold_a_compact_source_give_none() {
        // Texels wider than the ring: no background to compare with, so no source — even
        // where one texel is far brighter than the rest.
        for (w, h) in [(2u32, 1u32), (2, 2), (4, 2)] {
            let img = crate::image::Image::from_fn(w, h, |x, y| if (x, y) == (0, 0) { Vec3::splat(1e3) } else { Vec3::ONE });
            let map = EnvMap::from_image(&img, EnvMapOptions::default(), std::path::Path::new("coarse")).unwrap();
            assert!(extract_lights(&map, ExtractOptions::default()).unwrap().0.is_empty(), "{w}x{h}");
        }
        // Fine enough, the same bright texel is a source.
        let img = crate::image::Image::from_fn(256, 128, |x, y| if (x, y) == (40, 30) { Vec3::splat(1e4) } else { Vec3::ONE });
        let map = EnvMap::from_image(&img, EnvMapOptions::default(), std::path::Path::new("fine")).unwrap();
        assert_eq!(extract_lights(&map, ExtractOptions::default()).unwrap().0.len(), 1);
    }
}
