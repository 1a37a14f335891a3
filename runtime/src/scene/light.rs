//! Lights, with the conventions of docs/DESIGN.md §8.
//!
//! - A directional light's `dir_to_light` points *toward* the light (Mitsuba's
//!   `direction` is its negative); `irradiance` is per unit area perpendicular to the beam.
//! - A point light's `intensity` is per steradian, with 1/d² falloff.
//!
//! Both carry linear RGB.

use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    Directional { dir_to_light: Vec3, irradiance: Vec3 },
    Point { position: Vec3, intensity: Vec3 },
}

/// What a light delivers at a point: the unit direction toward the light, the
/// irradiance perpendicular to that direction, and the distance (∞ for directional).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    pub wi: Vec3,
    pub irradiance: Vec3,
    pub distance: f32,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LightError {
    #[error("light direction {0} is zero or not finite")]
    BadDirection(Vec3),
    #[error("light power {0} must be finite and non-negative")]
    BadPower(Vec3),
    #[error("point light position {0} is not finite")]
    BadPosition(Vec3),
}

impl Light {
    /// A directional light; `dir_to_light` need not be normalized.
    /// Scaled by its largest component first, so that 1e30,0,0 (whose squared length
    /// overflows) and 1e-40,0,0 (whose squared length underflows) are +X, not zero.
    pub fn directional(dir_to_light: Vec3, irradiance: Vec3) -> Light {
        let m = dir_to_light.abs().max_element();
        let d = if m > 0.0 && dir_to_light.is_finite() { (dir_to_light / m).normalize_or_zero() } else { dir_to_light };
        Light::Directional { dir_to_light: d, irradiance }
    }

    pub fn validate(&self) -> Result<(), LightError> {
        let power = match *self {
            Light::Directional { dir_to_light, irradiance } => {
                if !dir_to_light.is_finite() || dir_to_light.length_squared() < 0.5 {
                    return Err(LightError::BadDirection(dir_to_light));
                }
                irradiance
            }
            Light::Point { position, intensity } => {
                if !position.is_finite() {
                    return Err(LightError::BadPosition(position));
                }
                intensity
            }
        };
        if !power.is_finite() || power.min_element() < 0.0 {
            return Err(LightError::BadPower(power));
        }
        Ok(())
    }

    /// Incident light at world point `p`.
    pub fn sample(&self, p: Vec3) -> LightSample {
        match *self {
            Light::Directional { dir_to_light, irradiance } => LightSample { wi: dir_to_light, irradiance, distance: f32::INFINITY },
            Light::Point { position, intensity } => {
                let v = position - p;
                let d2 = v.length_squared().max(1e-12);
                let d = d2.sqrt();
                LightSample { wi: v / d, irradiance: intensity / d2, distance: d }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_falls_off_as_inverse_square() {
        let l = Light::Point { position: Vec3::new(0.0, 0.0, 2.0), intensity: Vec3::splat(8.0) };
        let s = l.sample(Vec3::ZERO);
        assert!((s.irradiance.x - 2.0).abs() < 1e-6 && s.wi.abs_diff_eq(Vec3::Z, 1e-6) && (s.distance - 2.0).abs() < 1e-6);
    }

    #[test]
    fn directional_light_points_toward_the_light() {
        let l = Light::directional(Vec3::new(0.0, 0.0, 3.0), Vec3::ONE);
        assert_eq!(l.sample(Vec3::new(5.0, 1.0, 0.0)).wi, Vec3::Z);
        assert!(Light::directional(Vec3::ZERO, Vec3::ONE).validate().is_err());
        // Lengths that overflow or underflow when squared still give a direction.
        for (d, want) in [(Vec3::new(1e30, 0.0, 0.0), Vec3::X), (Vec3::new(1e-40, 0.0, 0.0), Vec3::X), (Vec3::new(f32::MAX, f32::MAX, 0.0), Vec3::new(1.0, 1.0, 0.0).normalize())] {
            let l = Light::directional(d, Vec3::ONE);
            assert!(l.validate().is_ok(), "{d}");
            assert!(l.sample(Vec3::ZERO).wi.abs_diff_eq(want, 1e-6), "{d}");
        }
        // A bad direction is reported as given.
        let e = Light::directional(Vec3::new(f32::NAN, 0.0, 1.0), Vec3::ONE).validate().unwrap_err().to_string();
        assert!(e.contains("NaN"), "{e}");
        assert!(Light::directional(Vec3::Z, Vec3::new(1.0, -1.0, 0.0)).validate().is_err());
    }
}
