//! Cameras, with Mitsuba 3's conventions (docs/DESIGN.md §8).
//!
//! - `look_at`: forward = normalize(target − origin), image right = normalize(forward × up),
//!   image up = right × forward.
//! - Perspective `fov` is the *horizontal* field of view in degrees (Mitsuba's
//!   `fov_axis = "x"`); orthographic `extent` is the view's full width in world units
//!   (Mitsuba: `to_world = look_at · scale(extent/2)`).
//! - Pixel (c, r) has its centre at (c + 0.5, r + 0.5); row 0 is the top of the image.
//!
//! Every renderer (reference path tracer, CPU hybrid renderer, GPU renderer) builds its
//! rays or its clip transform from this one type, so their images line up pixel for pixel.

use glam::{Mat4, Vec2, Vec3, Vec4};

use super::ray::Ray;

/// How the camera projects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Horizontal field of view in degrees, in (0, 180).
    Perspective { fov_x_deg: f32 },
    /// Full width of the view in world units, > 0.
    Orthographic { extent: f32 },
}

/// A pinhole or orthographic camera looking from `origin` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub origin: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub projection: Projection,
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
}

/// The camera's orthonormal frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
}

/// Why a camera cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    #[error("camera origin and target coincide (or are not finite): origin {origin}, target {target}")]
    DegenerateDirection { origin: Vec3, target: Vec3 },
    #[error("camera up vector {up} is parallel to the view direction {forward} (or not finite)")]
    DegenerateUp { up: Vec3, forward: Vec3 },
    #[error("field of view {0}° is outside (0°, 180°)")]
    BadFov(f32),
    #[error("orthographic extent {0} must be a positive, finite width in world units")]
    BadExtent(f32),
    #[error("image size {0}x{1} is empty or larger than 16384 on a side")]
    BadSize(u32, u32),
}

impl Camera {
    /// Checks the parameters; every constructor path of a command should call this
    /// before rendering so that a bad flag gives an error, not a black or NaN image.
    pub fn validate(&self) -> Result<CameraFrame, CameraError> {
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(CameraError::BadSize(self.width, self.height));
        }
        match self.projection {
            Projection::Perspective { fov_x_deg } => {
                if !(fov_x_deg > 0.0 && fov_x_deg < 180.0) {
                    return Err(CameraError::BadFov(fov_x_deg));
                }
            }
            Projection::Orthographic { extent } => {
                if !(extent > 0.0 && extent.is_finite()) {
                    return Err(CameraError::BadExtent(extent));
                }
            }
        }
        let d = self.target - self.origin;
        if !d.is_finite() || d.length_squared() <= f32::MIN_POSITIVE {
            return Err(CameraError::DegenerateDirection { origin: self.origin, target: self.target });
        }
        let forward = d.normalize();
        let r = forward.cross(self.up);
        if !r.is_finite() || r.length() <= 1e-6 * self.up.length().max(1e-30) {
            return Err(CameraError::DegenerateUp { up: self.up, forward });
        }
        let right = r.normalize();
        let up = right.cross(forward);
        Ok(CameraFrame { forward, right, up })
    }

    /// The frame; falls back to a valid frame for degenerate input. Prefer `validate`.
    pub fn frame(&self) -> CameraFrame {
        self.validate().unwrap_or(CameraFrame { forward: -Vec3::Z, right: Vec3::X, up: Vec3::Y })
    }

    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }

    /// Half-extents of the image plane at unit distance (perspective) or in world units
    /// (orthographic), along right and up.
    pub fn half_extents(&self) -> Vec2 {
        let hx = match self.projection {
            Projection::Perspective { fov_x_deg } => (fov_x_deg.to_radians() * 0.5).tan(),
            Projection::Orthographic { extent } => extent * 0.5,
        };
        Vec2::new(hx, hx / self.aspect())
    }

    /// Normalized device position in [−1, 1]² (x right, y up) of image position
    /// `(px, py)` in pixels (continuous; a pixel's centre is at (c + 0.5, r + 0.5)).
    pub fn ndc(&self, px: f32, py: f32) -> Vec2 {
        Vec2::new(2.0 * px / self.width as f32 - 1.0, 1.0 - 2.0 * py / self.height as f32)
    }

    /// The primary ray through continuous image position `(px, py)`.
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let f = self.frame();
        let s = self.ndc(px, py) * self.half_extents();
        match self.projection {
            Projection::Perspective { .. } => {
                let d = (f.forward + s.x * f.right + s.y * f.up).normalize();
                Ray::new(self.origin, d)
            }
            Projection::Orthographic { .. } => Ray::new(self.origin + s.x * f.right + s.y * f.up, f.forward),
        }
    }

    /// Where world point `p` lands in the image, in continuous pixel coordinates, or
    /// `None` when it is behind a perspective camera.
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let f = self.frame();
        let v = p - self.origin;
        let (x, y, z) = (v.dot(f.right), v.dot(f.up), v.dot(f.forward));
        let s = match self.projection {
            Projection::Perspective { .. } => {
                if z <= 0.0 {
                    return None;
                }
                Vec2::new(x / z, y / z)
            }
            Projection::Orthographic { .. } => Vec2::new(x, y),
        };
        let ndc = s / self.half_extents();
        Some(Vec2::new((ndc.x + 1.0) * 0.5 * self.width as f32, (1.0 - ndc.y) * 0.5 * self.height as f32))
    }

    /// World-to-view matrix in a right-handed view space with x = right, y = up and the
    /// camera looking down −z.
    pub fn view_matrix(&self) -> Mat4 {
        let f = self.frame();
        let rot = Mat4::from_cols(
            Vec4::new(f.right.x, f.up.x, -f.forward.x, 0.0),
            Vec4::new(f.right.y, f.up.y, -f.forward.y, 0.0),
            Vec4::new(f.right.z, f.up.z, -f.forward.z, 0.0),
            Vec4::W,
        );
        rot * Mat4::from_translation(-self.origin)
    }

    /// View-to-clip matrix for Vulkan: clip y points *down* (row 0 at the top, as our
    /// images), depth in [0, 1] with reversed-Z off (near → 0, far → 1).
    pub fn projection_matrix(&self, near: f32, far: f32) -> Mat4 {
        let h = self.half_extents();
        match self.projection {
            Projection::Perspective { .. } => {
                // x_ndc = x / (−z·hx), y_ndc = −y / (−z·hy), z_ndc = far(z + near)/(z(near − far))...
                let a = far / (near - far);
                let b = near * far / (near - far);
                Mat4::from_cols(
                    Vec4::new(1.0 / h.x, 0.0, 0.0, 0.0),
                    Vec4::new(0.0, -1.0 / h.y, 0.0, 0.0),
                    Vec4::new(0.0, 0.0, a, -1.0),
                    Vec4::new(0.0, 0.0, b, 0.0),
                )
            }
            Projection::Orthographic { .. } => {
                let a = 1.0 / (near - far);
                let b = near / (near - far);
                Mat4::from_cols(
                    Vec4::new(1.0 / h.x, 0.0, 0.0, 0.0),
                    Vec4::new(0.0, -1.0 / h.y, 0.0, 0.0),
                    Vec4::new(0.0, 0.0, a, 0.0),
                    Vec4::new(0.0, 0.0, b, 1.0),
                )
            }
        }
    }

    /// An orthographic camera aimed at `center` from the direction (θ, φ) in degrees
    /// (θ from +Z, φ from +X), image up = (−cosθ cosφ, −cosθ sinφ, sinθ), at distance
    /// `distance`. This is the `--view-angles` shorthand; at θ = 0 the image up is −X.
    pub fn orbit_orthographic(theta_deg: f32, phi_deg: f32, center: Vec3, distance: f32, extent: f32, width: u32, height: u32) -> Camera {
        let dir = direction_from_angles(theta_deg, phi_deg);
        let (st, ct) = theta_deg.to_radians().sin_cos();
        let (sp, cp) = phi_deg.to_radians().sin_cos();
        Camera {
            origin: center + distance * dir,
            target: center,
            up: Vec3::new(-ct * cp, -ct * sp, st),
            projection: Projection::Orthographic { extent },
            width,
            height,
        }
    }
}

/// Unit direction at polar angle θ from +Z and azimuth φ from +X (degrees).
pub fn direction_from_angles(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    Vec3::new(st * cp, st * sp, ct)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn persp() -> Camera {
        Camera {
            origin: Vec3::new(0.0, -5.0, 2.0),
            target: Vec3::ZERO,
            up: Vec3::Z,
            projection: Projection::Perspective { fov_x_deg: 40.0 },
            width: 64,
            height: 48,
        }
    }

    #[test]
    fn frame_is_right_handed_look_at() {
        let f = persp().validate().unwrap();
        // Looking along +y from −y with z up: right is +x.
        assert!(f.right.abs_diff_eq(Vec3::X, 1e-6), "{:?}", f.right);
        assert!(f.up.z > 0.9 && f.up.dot(f.forward).abs() < 1e-6);
    }

    #[test]
    fn point_right_and_above_lands_right_and_up() {
        for cam in [persp(), Camera { projection: Projection::Orthographic { extent: 4.0 }, ..persp() }] {
            let c = cam.project(Vec3::ZERO).unwrap();
            let p = cam.project(Vec3::new(0.5, 0.0, 0.5)).unwrap();
            assert!((c - Vec2::new(32.0, 24.0)).length() < 1e-3, "target at the centre: {c}");
            assert!(p.x > c.x && p.y < c.y, "right and up: {p} vs {c}");
        }
    }

    #[test]
    fn ray_and_project_are_inverse() {
        for cam in [persp(), Camera { projection: Projection::Orthographic { extent: 3.0 }, ..persp() }] {
            for (px, py) in [(0.5, 0.5), (10.25, 40.0), (63.5, 47.5)] {
                let r = cam.ray(px, py);
                let q = cam.project(r.at(3.0)).unwrap();
                assert!((q - Vec2::new(px, py)).length() < 1e-3, "{q} vs {px},{py}");
            }
        }
    }

    #[test]
    fn horizontal_fov_spans_the_width() {
        let cam = Camera { origin: Vec3::ZERO, target: -Vec3::Z, up: Vec3::Y, projection: Projection::Perspective { fov_x_deg: 90.0 }, width: 200, height: 100 };
        // The left edge of the image (px = 0) is 45° off axis.
        let r = cam.ray(0.0, 50.0);
        assert!((r.d.angle_between(-Vec3::Z).to_degrees() - 45.0).abs() < 1e-3);
        let ortho = Camera { projection: Projection::Orthographic { extent: 2.0 }, ..cam };
        assert!((ortho.ray(0.0, 50.0).o.x + 1.0).abs() < 1e-6 && (ortho.ray(200.0, 50.0).o.x - 1.0).abs() < 1e-6);
    }

    #[test]
    fn clip_matrix_matches_project() {
        for cam in [persp(), Camera { projection: Projection::Orthographic { extent: 3.0 }, ..persp() }] {
            let m = cam.projection_matrix(0.1, 100.0) * cam.view_matrix();
            let p = Vec3::new(0.3, 0.2, 0.7);
            let c = m * p.extend(1.0);
            let ndc = c.truncate() / c.w;
            // Vulkan: x right, y down, both in [−1, 1] across the image.
            let px = Vec2::new((ndc.x + 1.0) * 0.5 * 64.0, (ndc.y + 1.0) * 0.5 * 48.0);
            let q = cam.project(p).unwrap();
            assert!((px - q).length() < 1e-3, "{px} vs {q}");
            assert!(ndc.z > 0.0 && ndc.z < 1.0);
        }
    }

    #[test]
    fn degenerate_cameras_are_rejected() {
        assert!(matches!(Camera { up: Vec3::new(0.0, 5.0, -2.0), ..persp() }.validate(), Err(CameraError::DegenerateUp { .. })));
        assert!(matches!(Camera { target: persp().origin, ..persp() }.validate(), Err(CameraError::DegenerateDirection { .. })));
        assert!(matches!(Camera { projection: Projection::Perspective { fov_x_deg: 180.0 }, ..persp() }.validate(), Err(CameraError::BadFov(_))));
        assert!(matches!(Camera { projection: Projection::Orthographic { extent: f32::NAN }, ..persp() }.validate(), Err(CameraError::BadExtent(_))));
        assert!(matches!(Camera { width: 0, ..persp() }.validate(), Err(CameraError::BadSize(..))));
    }

    #[test]
    fn orbit_shorthand_image_up() {
        let cam = Camera::orbit_orthographic(30.0, 90.0, Vec3::ZERO, 10.0, 2.0, 32, 32);
        let f = cam.validate().unwrap();
        assert!(f.forward.abs_diff_eq(-direction_from_angles(30.0, 90.0), 1e-6));
        assert!(f.up.abs_diff_eq(Vec3::new(0.0, -(30f32.to_radians().cos()), 30f32.to_radians().sin()), 1e-5), "{:?}", f.up);
        // Straight down: image up is −X, so right is... forward (−Z) × (−X) = +Y.
        let top = Camera::orbit_orthographic(0.0, 0.0, Vec3::ZERO, 10.0, 2.0, 32, 32).validate().unwrap();
        assert!(top.right.abs_diff_eq(Vec3::Y, 1e-6), "{:?}", top.right);
    }
}
