//! Flags shared by every command that renders: camera, light, image size, exposure.
//! One definition so that `fabric reference`, `fabric render` (GPU and CPU) and the
//! bench mean the same thing by the same flag (docs/DESIGN.md §8).

use anyhow::{Context, Result, bail};
use clap::Args;
use fabric_runtime::scene::{Aabb, Camera, EnvMap, EnvMapOptions, Light, Projection, Sky, direction_from_angles};
use glam::Vec3;

/// Parses "X,Y,Z".
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s.split(',').map(|p| p.trim().parse::<f32>().map_err(|e| format!("'{p}' in '{s}': {e}"))).collect::<Result<_, _>>()?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(*x, *y, *z)),
        [_, _, _] => Err(format!("'{s}' has a non-finite component")),
        _ => Err(format!("expected three comma-separated numbers X,Y,Z, got '{s}'")),
    }
}

/// Parses "V" (grey) or "R,G,B".
pub fn parse_rgb(s: &str) -> Result<Vec3, String> {
    if !s.contains(',') {
        let v: f32 = s.trim().parse().map_err(|e| format!("'{s}': {e}"))?;
        if !v.is_finite() {
            return Err(format!("'{s}' is not finite"));
        }
        return Ok(Vec3::splat(v));
    }
    parse_vec3(s)
}

/// Parses "θ,φ" in degrees.
pub fn parse_angles(s: &str) -> Result<(f32, f32), String> {
    let v: Vec<f32> = s.split(',').map(|p| p.trim().parse::<f32>().map_err(|e| format!("'{p}' in '{s}': {e}"))).collect::<Result<_, _>>()?;
    match v.as_slice() {
        [t, p] if t.is_finite() && p.is_finite() => Ok((*t, *p)),
        _ => Err(format!("expected θ,φ in degrees, got '{s}'")),
    }
}

/// Parses "WxH".
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("expected WxH (e.g. 640x360), got '{s}'"))?;
    let w: u32 = w.trim().parse().map_err(|e| format!("width '{w}': {e}"))?;
    let h: u32 = h.trim().parse().map_err(|e| format!("height '{h}': {e}"))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("image size {w}x{h} must be between 1 and 16384 on each side"));
    }
    Ok((w, h))
}

#[derive(Args, Clone, Debug, Default)]
pub struct CameraArgs {
    /// Camera position (world units).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub origin: Option<Vec3>,
    /// Point the camera looks at.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<Vec3>,
    /// Up vector of the look_at frame.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, default_value = "0,0,1")]
    pub up: Vec3,
    /// Perspective camera: horizontal field of view in degrees.
    #[arg(long, conflicts_with = "extent")]
    pub fov: Option<f32>,
    /// Orthographic camera: full width of the view in world units.
    #[arg(long)]
    pub extent: Option<f32>,
    /// Orthographic camera aimed at the centre of the subject's top face from direction
    /// θ,φ (degrees; θ from +Z, φ from +X); extent = the subject's x width.
    #[arg(long, value_parser = parse_angles, allow_hyphen_values = true, conflicts_with_all = ["origin", "fov"])]
    pub view_angles: Option<(f32, f32)>,
    /// Image size in pixels.
    #[arg(long, value_parser = parse_size, default_value = "640x360")]
    pub size: (u32, u32),
}

/// What the GPU draws when no hybrid model is given: a base mesh with a checker
/// texture, and the device to draw it on.
#[derive(Args, Clone, Debug)]
pub struct MeshSceneArgs {
    /// Base mesh: plane, sphere, cylinder, or a path to an .obj file; with a hybrid model
    /// the fabric is drawn on it, tiled over its UVs (default: sphere without a model;
    /// `view` with a model: plane; `render` with a model and no mesh draws its tile).
    #[arg(long)]
    pub mesh: Option<String>,
    /// Colour multiplying the mesh's checker texture (V or R,G,B, linear).
    #[arg(long, value_parser = parse_rgb, default_value = "1")]
    pub base_color: Vec3,
    /// Tile repeats per UV unit of the mesh (U or U,V) when a hybrid model is drawn on it.
    #[arg(long, value_parser = parse_uv_scale, default_value = "8")]
    pub uv_scale: glam::Vec2,
    /// Vulkan device to use (substring of its name; see `fabric devices`).
    #[arg(long)]
    pub device: Option<String>,
}

#[derive(Args, Clone, Debug, Default)]
pub struct LightArgs {
    /// Directional light: direction *toward* the light.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, conflicts_with_all = ["point_light", "light_angles"])]
    pub light_dir: Option<Vec3>,
    /// Directional light toward direction θ,φ (degrees; θ from +Z, φ from +X).
    #[arg(long, value_parser = parse_angles, allow_hyphen_values = true, conflicts_with = "point_light")]
    pub light_angles: Option<(f32, f32)>,
    /// Irradiance of the directional light, perpendicular to the beam (V or R,G,B).
    #[arg(long, value_parser = parse_rgb, default_value = "1")]
    pub irradiance: Vec3,
    /// Point light position.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub point_light: Option<Vec3>,
    /// Point light intensity per steradian (V or R,G,B), 1/d² falloff.
    #[arg(long, value_parser = parse_rgb, default_value = "1")]
    pub intensity: Vec3,
}

#[derive(Args, Clone, Debug)]
pub struct OutputArgs {
    /// Output image: .exr (linear radiance) or .png (sRGB(clamp(exposure·L))).
    #[arg(long, short)]
    pub out: std::path::PathBuf,
    /// Exposure applied before the sRGB mapping of PNG output.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub exposure: f32,
}

impl OutputArgs {
    /// Checks the output path and exposure before any work is done.
    pub fn validate(&self) -> Result<()> {
        match self.out.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
            Some("png") | Some("exr") => {}
            _ => bail!("{}: unknown image extension (use .exr or .png)", self.out.display()),
        }
        if !(self.exposure.is_finite() && self.exposure > 0.0) {
            bail!("--exposure {} must be a positive number", self.exposure);
        }
        Ok(())
    }
}

impl CameraArgs {
    /// The camera for a subject occupying `bounds`. Without flags: a perspective view
    /// of the subject from above and in front (θ = 50°, φ = −90°) that frames it.
    pub fn camera(&self, bounds: Aabb) -> Result<Camera> {
        let (width, height) = self.size;
        let center = bounds.center();
        let radius = 0.5 * bounds.size().length();
        let cam = if let Some((theta, phi)) = self.view_angles {
            let top = Vec3::new(center.x, center.y, bounds.max.z);
            let extent = self.extent.unwrap_or(bounds.size().x);
            Camera::orbit_orthographic(theta, phi, top, 2.0 * radius + 1.0, extent, width, height)
        } else {
            let projection = match (self.fov, self.extent) {
                (_, Some(extent)) => Projection::Orthographic { extent },
                (Some(fov), None) => Projection::Perspective { fov_x_deg: fov },
                (None, None) => Projection::Perspective { fov_x_deg: 40.0 },
            };
            let target = self.target.unwrap_or(center);
            let origin = match self.origin {
                Some(o) => o,
                None => {
                    let fov = match projection {
                        Projection::Perspective { fov_x_deg } => fov_x_deg,
                        Projection::Orthographic { .. } => 40.0,
                    };
                    let vfov_half = ((fov.to_radians() * 0.5).tan() / (width as f32 / height as f32)).atan();
                    let dist = radius / vfov_half.sin().max(1e-3);
                    target + dist * direction_from_angles(50.0, -90.0)
                }
            };
            Camera { origin, target, up: self.up, projection, width, height }
        };
        cam.validate().context("invalid camera flags")?;
        Ok(cam)
    }
}

impl LightArgs {
    /// Whether any light flag was given.
    pub fn given(&self) -> bool {
        self.point_light.is_some() || self.light_dir.is_some() || self.light_angles.is_some()
    }

    /// The light. Without flags: a unit-irradiance directional light from θ = 30°, φ = −60°.
    pub fn light(&self) -> Result<Light> {
        let light = match (self.point_light, self.light_dir, self.light_angles) {
            (Some(p), None, None) => Light::Point { position: p, intensity: self.intensity },
            (None, Some(d), None) => Light::directional(d, self.irradiance),
            (None, None, Some((t, p))) => Light::directional(direction_from_angles(t, p), self.irradiance),
            (None, None, None) => Light::directional(direction_from_angles(30.0, -60.0), self.irradiance),
            _ => bail!("give one light: --light-dir, --light-angles or --point-light"),
        };
        light.validate().context("invalid light flags")?;
        Ok(light)
    }
}

/// Environment lighting flags (runtime/src/scene/envmap.rs gives the orientation, which
/// is Mitsuba 3's `envmap` placed Z up).
#[derive(Args, Clone, Debug)]
pub struct EnvArgs {
    /// Environment map: an equirectangular .exr (linear RGB) or .png, or `sky` for the
    /// built-in procedural sky. With it, a delta light is added only if a light flag is given.
    #[arg(long)]
    pub envmap: Option<String>,
    /// Multiplies the map's radiance (Mitsuba's `scale`).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub envmap_scale: f32,
    /// Turns the map about +Z (degrees).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub envmap_rotate: f32,
    /// Rays that miss the fabric see black instead of the map.
    #[arg(long)]
    pub no_background: bool,
}

impl Default for EnvArgs {
    fn default() -> Self {
        EnvArgs { envmap: None, envmap_scale: 1.0, envmap_rotate: 0.0, no_background: false }
    }
}

impl EnvArgs {
    /// The map, loaded and checked, or None without `--envmap`.
    pub fn env_map(&self) -> Result<Option<EnvMap>> {
        let options = EnvMapOptions { scale: self.envmap_scale, rotate_deg: self.envmap_rotate };
        match self.envmap.as_deref() {
            None => {
                if self.envmap_scale != 1.0 || self.envmap_rotate != 0.0 {
                    bail!("--envmap-scale and --envmap-rotate need --envmap FILE|sky");
                }
                Ok(None)
            }
            Some("sky") => Ok(Some(Sky::default().env_map(options)?)),
            Some(path) => Ok(Some(EnvMap::load(std::path::Path::new(path), options).with_context(|| format!("cannot use --envmap {path}"))?)),
        }
    }
}

/// Material flags that override `material.toml` wherever a fabric volume is read.
#[derive(Args, Clone, Debug, Default)]
pub struct MaterialArgs {
    /// σ_t = density_scale·ρ·σ(ω), per world unit (overrides material.toml).
    #[arg(long)]
    pub density_scale: Option<f32>,
    /// SGGX fiber roughness σ in (0, 1] (overrides material.toml).
    #[arg(long)]
    pub roughness: Option<f32>,
}

impl MaterialArgs {
    /// The overrides, checked (a bad flag fails before any file is read).
    pub fn overrides(&self) -> Result<fabric_baker::volume::MaterialOverrides> {
        let o = fabric_baker::volume::MaterialOverrides { density_scale: self.density_scale, roughness: self.roughness };
        fabric_baker::volume::material::check_overrides(&o)?;
        Ok(o)
    }
}

/// Parses "XxYxZ" voxel counts.
pub fn parse_dims(s: &str) -> Result<[usize; 3], String> {
    let v: Vec<usize> = s.split(['x', 'X']).map(|p| p.trim().parse::<usize>().map_err(|e| format!("'{p}' in '{s}': {e}"))).collect::<Result<_, _>>()?;
    match v.as_slice() {
        [x, y, z] if *x > 0 && *y > 0 && *z > 0 => Ok([*x, *y, *z]),
        [_, _, _] => Err(format!("'{s}': every axis needs at least one voxel")),
        _ => Err(format!("expected XxYxZ (e.g. 256x256x48), got '{s}'")),
    }
}

/// `U` or `U,V`: positive, finite repeats per UV unit.
fn parse_uv_scale(s: &str) -> Result<glam::Vec2, String> {
    let parts: Vec<&str> = s.split(',').collect();
    let nums: Result<Vec<f32>, _> = parts.iter().map(|p| p.trim().parse::<f32>()).collect();
    let v = match nums.map_err(|e| format!("'{s}': {e}"))?.as_slice() {
        [u] => glam::Vec2::splat(*u),
        [u, v] => glam::Vec2::new(*u, *v),
        _ => return Err(format!("'{s}': expected U or U,V")),
    };
    if !(v.is_finite() && v.min_element() > 0.0) {
        return Err(format!("'{s}': repeats per UV unit must be positive and finite"));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsers_reject_garbage() {
        assert_eq!(parse_vec3("1,-2,3.5").unwrap(), Vec3::new(1.0, -2.0, 3.5));
        assert!(parse_vec3("1,2").is_err() && parse_vec3("a,b,c").is_err() && parse_vec3("1,inf,2").is_err());
        assert_eq!(parse_size("640x360").unwrap(), (640, 360));
        assert!(parse_size("0x10").is_err() && parse_size("640").is_err() && parse_size("99999x2").is_err());
        assert_eq!(parse_rgb("0.5").unwrap(), Vec3::splat(0.5));
        assert!(parse_angles("30").is_err());
    }

    #[test]
    fn default_camera_frames_the_subject() {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let cam = CameraArgs { size: (64, 64), up: Vec3::Z, ..Default::default() }.camera(b).unwrap();
        for corner in [b.min, b.max, Vec3::new(1.0, -1.0, 1.0), Vec3::new(-1.0, 1.0, -1.0)] {
            let p = cam.project(corner).unwrap();
            assert!(p.x >= 0.0 && p.x <= 64.0 && p.y >= 0.0 && p.y <= 64.0, "{corner} -> {p}");
        }
    }
}

/// Most worker threads a command starts (`--threads`): far more than any machine's cores,
/// and a typo such as 4294967295 an error instead of a runaway spawn.
pub const MAX_THREADS: usize = 1024;
/// Most samples per pixel or texel any command takes (the bake's `--spp` bound): beyond
/// it a render runs for days, not a useful refinement.
pub const MAX_SPP: u32 = 65536;
/// Most frames `--repeat` renders.
pub const MAX_REPEAT: u32 = 10_000;

/// Checks, before any work, that `path` can be written as a file: not a directory, its
/// folder creatable and writable (a probe file is made and removed there). `flag` names
/// the option in the error.
pub fn check_writable_file(path: &std::path::Path, flag: &str) -> anyhow::Result<()> {
    use anyhow::Context;
    if path.is_dir() {
        anyhow::bail!("{flag} {}: is a directory; give a file name", path.display());
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(std::path::Path::new("."));
    std::fs::create_dir_all(dir).with_context(|| format!("{flag} {}: cannot create its folder {}", path.display(), dir.display()))?;
    let probe = dir.join(format!(".fabric-write-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").with_context(|| format!("{flag} {}: cannot write in {}", path.display(), dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}
