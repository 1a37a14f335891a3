//! `material.toml`: the per-fabric constants that are not per voxel, and the
//! `--density-scale` / `--roughness` flags that override them wherever a volume is read.
//!
//! ```toml
//! density_scale = 166.7   # σ_t = density_scale · ρ · σ(ω), per world unit
//! roughness = 0.2         # SGGX fiber roughness σ in (0, 1]
//! [generator]             # optional provenance written by `fabric gen`; not interpreted here
//! ```
//!
//! Unknown keys are an error (a misspelt `density_scal` must not fall back to a default
//! silently). A missing file or key takes [`MaterialParams::default`].

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::error::VolumeError;
use super::grid::MaterialParams;

/// Values given on the command line; `Some` wins over `material.toml`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaterialOverrides {
    pub density_scale: Option<f32>,
    pub roughness: Option<f32>,
}

/// The contents of `material.toml`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialFile {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub density_scale: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roughness: Option<f32>,
    /// Provenance (generator preset, seed, parameters); kept verbatim.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub generator: Option<toml::Table>,
}

impl MaterialFile {
    /// Reads `path`; a missing file is an empty one.
    pub fn read_or_default(path: &Path) -> Result<MaterialFile, VolumeError> {
        match std::fs::read_to_string(path) {
            Ok(text) => MaterialFile::parse(&text, path),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(MaterialFile::default()),
            Err(e) => Err(VolumeError::io(path, e)),
        }
    }

    pub fn parse(text: &str, path: &Path) -> Result<MaterialFile, VolumeError> {
        toml::from_str(text).map_err(|e| VolumeError::Material { path: path.to_path_buf(), message: e.to_string().trim_end().to_string() })
    }

    pub fn write(&self, path: &Path) -> Result<(), VolumeError> {
        let text = toml::to_string(self).map_err(|e| VolumeError::Material { path: path.to_path_buf(), message: format!("cannot serialize: {e}") })?;
        std::fs::write(path, text).map_err(|e| VolumeError::io(path, e))
    }

    /// The material after overrides, checked. `path` names the file in errors; an
    /// override is reported as the flag that gave it.
    pub fn resolve(&self, overrides: &MaterialOverrides, path: &Path) -> Result<MaterialParams, VolumeError> {
        let d = MaterialParams::default();
        let density_scale = pick(overrides.density_scale, self.density_scale, d.density_scale, "--density-scale", "density_scale", path);
        let roughness = pick(overrides.roughness, self.roughness, d.roughness, "--roughness", "roughness", path);
        let m = MaterialParams { density_scale: density_scale.0, roughness: roughness.0 };
        check(m.density_scale, density_scale.1, |v| (DENSITY_SCALE_MIN..=DENSITY_SCALE_MAX).contains(&v), DENSITY_SCALE_RULE)?;
        check(m.roughness, roughness.1, |v| v > 0.0 && v <= 1.0, "must be in (0, 1]")?;
        Ok(m)
    }
}

/// The density scale's range, per world unit. Above it the medium is opaque at any voxel
/// size and the path tracer's delta tracking takes about σ_t · length steps per path
/// (1e8 ran for minutes at 256 paths); below it the cloth is empty and the number
/// prints as 0 in material.toml.
pub const DENSITY_SCALE_MIN: f32 = 1e-6;
pub const DENSITY_SCALE_MAX: f32 = 1e6;
const DENSITY_SCALE_RULE: &str = "must be in [1e-6, 1e6] per world unit";

type Source = (String, std::path::PathBuf);

fn pick(flag: Option<f32>, file: Option<f32>, default: f32, flag_name: &str, key: &str, path: &Path) -> (f32, Source) {
    match (flag, file) {
        (Some(v), _) => (v, (format!("{flag_name} {v}"), "command line".into())),
        (None, Some(v)) => (v, (format!("{key} = {v}"), path.to_path_buf())),
        (None, None) => (default, (format!("default {key} {default}"), path.to_path_buf())),
    }
}

fn check(v: f32, (what, path): Source, ok: impl Fn(f32) -> bool, rule: &str) -> Result<(), VolumeError> {
    if ok(v) { Ok(()) } else { Err(VolumeError::Material { path, message: format!("{what}: {rule}") }) }
}

/// Checks override flags on their own (before any file is read).
pub fn check_overrides(o: &MaterialOverrides) -> Result<(), VolumeError> {
    MaterialFile::default().resolve(o, Path::new("material.toml")).map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_overrides_and_errors() {
        let p = Path::new("fab/material.toml");
        let f = MaterialFile::parse("density_scale = 200.0\nroughness = 0.25\n", p).unwrap();
        let m = f.resolve(&MaterialOverrides::default(), p).unwrap();
        assert_eq!((m.density_scale, m.roughness), (200.0, 0.25));
        let m = f.resolve(&MaterialOverrides { density_scale: None, roughness: Some(0.05) }, p).unwrap();
        assert_eq!((m.density_scale, m.roughness), (200.0, 0.05));
        assert_eq!(MaterialFile::parse("", p).unwrap().resolve(&MaterialOverrides::default(), p).unwrap(), MaterialParams::default());

        for bad in ["density_scale = 1e30\n", "density_scale = 1e-40\n"] {
            let e = MaterialFile::parse(bad, p).unwrap().resolve(&MaterialOverrides::default(), p).unwrap_err().to_string();
            assert!(e.contains("fab/material.toml") && e.contains("[1e-6, 1e6]"), "{e}");
        }
        let e = MaterialFile::parse("density_scal = 3\n", p).unwrap_err().to_string();
        assert!(e.contains("fab/material.toml") && e.contains("density_scal"), "{e}");
        let e = MaterialFile::parse("roughness = \"high\"\n", p).unwrap_err().to_string();
        assert!(e.contains("roughness"), "{e}");
        let e = MaterialFile::parse("roughness = 1.5\n", p).unwrap().resolve(&MaterialOverrides::default(), p).unwrap_err().to_string();
        assert!(e.contains("fab/material.toml") && e.contains("roughness = 1.5") && e.contains("(0, 1]"), "{e}");
        let e = f.resolve(&MaterialOverrides { density_scale: Some(-1.0), roughness: None }, p).unwrap_err().to_string();
        assert!(e.contains("--density-scale -1") && e.contains("command line"), "{e}");
        assert!(check_overrides(&MaterialOverrides { density_scale: Some(f32::NAN), roughness: None }).is_err());
    }
}
