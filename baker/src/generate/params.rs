//! Every parameter of the procedural fabric generator, with its unit. Lengths are in
//! millimetres (the world unit of generated volumes); angles in radians.
//!
//! The structure follows the textile hierarchy: fibers → plies → yarns (Zhao, Luan and
//! Bala 2016, "Fitting procedural yarn models for realistic cloth rendering", §3–4)
//! → weave, or fibers → a matted non-woven layer (felt). Parameters serialize to TOML
//! (`material.toml`'s `[generator]` table records them) and any of them can be
//! overridden by a dotted key (`--set fabric.yarn.plies=3`).

use serde::{Deserialize, Serialize};

use super::GenerateError;

/// All generator parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeneratorParams {
    /// Voxel edge (mm). Absent: chosen so that footroom + fabric body + headroom fills
    /// the z resolution exactly.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub voxel_size: Option<f32>,
    /// Empty space above the fabric body for flyaways (mm).
    pub headroom: f32,
    /// Empty space below the fabric body (mm).
    pub footroom: f32,
    pub fiber: FiberParams,
    pub material: MaterialSpec,
    pub fabric: FabricParams,
}

/// One fiber.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FiberParams {
    /// Fiber diameter (mm); 10–20 µm for cotton, wool and silk.
    pub diameter: f32,
    /// Per-fiber albedo variation: each fiber's colour is its yarn's times
    /// exp(variation · N(0, 1)), clamped to [0, 1].
    pub albedo_variation: f32,
}

/// What goes into `material.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// SGGX fiber roughness σ in (0, 1].
    pub roughness: f32,
    /// Optical depth across one fiber's diameter at ρ = 1 seen side-on:
    /// density_scale = optical_depth / diameter (per mm).
    pub fiber_optical_depth: f32,
}

/// Woven or non-woven.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum FabricParams {
    Woven(WovenParams),
    Felt(FeltParams),
}

/// The interlacing pattern of a woven fabric.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PatternKind {
    /// Over one, under one.
    Plain,
    /// Warp over `over` of every `repeat` wefts, shifted by `step` per warp (diagonals).
    Twill,
    /// Warp-faced satin: each warp goes under one weft of every `repeat`, the interlacing
    /// points shifted by `step` per warp (step coprime with repeat, not ±1).
    Satin,
}

/// A woven fabric: warp yarns run along y, weft yarns along x.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WovenParams {
    pub pattern: PatternKind,
    /// Pattern period (yarns) for twill and satin.
    pub repeat: u32,
    /// Twill: wefts each warp floats over per period.
    pub over: u32,
    /// Twill and satin: shift of the pattern from one warp to the next.
    pub step: u32,
    /// Nominal centre distance of warp yarns (mm); adjusted so a whole number of
    /// pattern and colour repeats fills the tile.
    pub warp_spacing: f32,
    /// Nominal centre distance of weft yarns (mm); adjusted likewise.
    pub weft_spacing: f32,
    /// Yarn width / spacing (1 = neighbours touch; above 1 they press together).
    pub cover: f32,
    /// Yarn thickness / width (woven yarns are flattened).
    pub flattening: f32,
    /// Vertical distance of crossing yarns' centres / their mean thickness (1 = touch).
    pub crimp: f32,
    /// Share of that crimp the warp takes (0.5: balanced; satins bend the warp around
    /// a nearly straight weft, so the weft stays below the warp floats).
    pub crimp_balance: f32,
    /// Warp colours (linear RGB albedo), cycled over the warps.
    pub warp_colors: Vec<[f32; 3]>,
    /// Weft colours, cycled over the wefts.
    pub weft_colors: Vec<[f32; 3]>,
    pub yarn: YarnParams,
}

/// One yarn: plies twisted together, each a bundle of twisted, migrating fibers, plus
/// flyaways (Zhao et al. 2016).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct YarnParams {
    /// Number of plies K.
    pub plies: u32,
    /// Ply twist around the yarn centre (turns per mm, signed: + is Z twist);
    /// rounded so that each tile holds whole turns.
    pub ply_twist: f32,
    /// Fiber twist around the ply centre (turns per mm, signed; usually opposite to the
    /// ply twist); rounded like the ply twist.
    pub fiber_twist: f32,
    /// Fibers per ply. Absent: from `packing`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fibers_per_ply: Option<u32>,
    /// Fiber volume fraction of a ply, used when `fibers_per_ply` is absent.
    pub packing: f32,
    /// Ply cross-section ellipse: semi-axes along the ply's radial and tangential
    /// directions, relative to a circle (Zhao: e_N, e_B).
    pub ply_ellipse: [f32; 2],
    /// Fiber distribution p(R) = (1 − 2ε)·((e − e^R)/(e − 1))^β + ε (Zhao Eq. 1).
    pub density_epsilon: f32,
    pub density_beta: f32,
    /// Fiber migration between R_min·r and R_max·r (Zhao Eq. 2).
    pub migration_rmin: f32,
    pub migration_rmax: f32,
    /// Length of one migration cycle (mm); 0 = no migration. Rounded to whole cycles per tile.
    pub migration_period: f32,
    pub flyaways: FlyawayParams,
}

/// Flyaway fibers of a yarn (Zhao et al. 2016 §4.2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlyawayParams {
    /// Hair-type flyaways per mm of ply.
    pub hair_density: f32,
    /// Hair root radius, relative to the ply radius (inside the ply: < 1).
    pub hair_rmin: f32,
    /// How far beyond the root a hair reaches, relative to the ply radius.
    pub hair_rspan: f32,
    /// Length of a hair along the yarn (mm).
    pub hair_zspan: f32,
    /// Spread of a hair's azimuth from root to tip (rad).
    pub hair_theta_span: f32,
    /// Probability that one migration cycle of a fiber is a loop.
    pub loop_probability: f32,
    /// Radius a loop reaches, relative to the ply radius (> 1 sticks out).
    pub loop_rmax: f32,
}

/// A non-woven felt: long curly fibers matted into a layer, hairy on top.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeltParams {
    /// Thickness of the matted layer (mm).
    pub thickness: f32,
    /// Fiber volume fraction of the layer.
    pub packing: f32,
    /// Mean fiber length (mm); lengths vary ±50 %.
    pub fiber_length: f32,
    /// Curliness: standard deviation of the heading change per √mm (rad).
    pub curl: f32,
    /// Standard deviation of a fiber's elevation from the layer plane (rad).
    pub tilt: f32,
    /// Fiber colours, picked at random per fiber.
    pub colors: Vec<[f32; 3]>,
    /// Hairs per mm² of surface.
    pub hair_density: f32,
    /// Mean hair length (mm).
    pub hair_length: f32,
    /// Mean hair elevation above the layer plane (rad).
    pub hair_elevation: f32,
    /// Loops per mm² of surface.
    pub loop_density: f32,
    /// Mean loop height above the surface (mm).
    pub loop_height: f32,
    /// Mean loop span along the surface (mm).
    pub loop_span: f32,
}

fn bad(key: &str, value: impl std::fmt::Display, rule: &str) -> GenerateError {
    GenerateError::Param { key: key.to_string(), value: value.to_string(), rule: rule.to_string() }
}

fn positive(key: &str, v: f32) -> Result<(), GenerateError> {
    if v.is_finite() && v > 0.0 { Ok(()) } else { Err(bad(key, v, "must be finite and > 0")) }
}

fn non_negative(key: &str, v: f32) -> Result<(), GenerateError> {
    if v.is_finite() && v >= 0.0 { Ok(()) } else { Err(bad(key, v, "must be finite and ≥ 0")) }
}

fn in_range(key: &str, v: f32, lo: f32, hi: f32) -> Result<(), GenerateError> {
    if v >= lo && v <= hi { Ok(()) } else { Err(bad(key, v, &format!("must be in [{lo}, {hi}]"))) }
}

fn colors(key: &str, cs: &[[f32; 3]]) -> Result<(), GenerateError> {
    if cs.is_empty() || cs.len() > 16 {
        return Err(bad(key, format!("{} colours", cs.len()), "needs 1 to 16 colours"));
    }
    for c in cs {
        if !c.iter().all(|v| (0.0..=1.0).contains(v)) {
            return Err(bad(key, format!("{c:?}"), "albedo channels must be in [0, 1]"));
        }
    }
    Ok(())
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

impl GeneratorParams {
    /// Checks every value; errors name the dotted key.
    pub fn validate(&self) -> Result<(), GenerateError> {
        if let Some(v) = self.voxel_size {
            positive("voxel_size", v)?;
        }
        non_negative("headroom", self.headroom)?;
        non_negative("footroom", self.footroom)?;
        // Bounds far outside real cloth (fibres 5–50 µm, yarns 0.1–2 mm apart) that keep
        // the generator's fibre, hair and step counts finite: 1e30 asked for more hairs
        // than memory holds, 1e-9 spacings for 27 GB.
        in_range("fiber.diameter", self.fiber.diameter, 1e-4, 1.0)?;
        in_range("fiber.albedo_variation", self.fiber.albedo_variation, 0.0, 1.0)?;
        if !(self.material.roughness > 0.0 && self.material.roughness <= 1.0) {
            return Err(bad("material.roughness", self.material.roughness, "must be in (0, 1]"));
        }
        positive("material.fiber_optical_depth", self.material.fiber_optical_depth)?;
        match &self.fabric {
            FabricParams::Woven(w) => w.validate(),
            FabricParams::Felt(f) => f.validate(),
        }
    }
}

impl WovenParams {
    fn validate(&self) -> Result<(), GenerateError> {
        match self.pattern {
            PatternKind::Plain => {}
            PatternKind::Twill => {
                if !(2..=64).contains(&self.repeat) {
                    return Err(bad("fabric.repeat", self.repeat, "twill needs a repeat in 2..=64"));
                }
                if self.over == 0 || self.over >= self.repeat {
                    return Err(bad("fabric.over", self.over, "twill needs 1 ≤ over < repeat"));
                }
                if self.step == 0 || self.step >= self.repeat {
                    return Err(bad("fabric.step", self.step, "twill needs 1 ≤ step < repeat"));
                }
            }
            PatternKind::Satin => {
                if !(5..=64).contains(&self.repeat) {
                    return Err(bad("fabric.repeat", self.repeat, "satin needs a repeat in 5..=64"));
                }
                if self.step < 2 || self.step >= self.repeat - 1 || gcd(self.step, self.repeat) != 1 {
                    return Err(bad("fabric.step", self.step, "satin needs 2 ≤ step ≤ repeat − 2, coprime with repeat"));
                }
            }
        }
        in_range("fabric.warp_spacing", self.warp_spacing, 1e-3, 100.0)?;
        in_range("fabric.weft_spacing", self.weft_spacing, 1e-3, 100.0)?;
        in_range("fabric.cover", self.cover, 0.3, 1.5)?;
        in_range("fabric.flattening", self.flattening, 0.1, 1.0)?;
        in_range("fabric.crimp", self.crimp, 0.0, 2.0)?;
        in_range("fabric.crimp_balance", self.crimp_balance, 0.0, 1.0)?;
        colors("fabric.warp_colors", &self.warp_colors)?;
        colors("fabric.weft_colors", &self.weft_colors)?;
        self.yarn.validate("fabric.yarn")
    }
}

impl YarnParams {
    fn validate(&self, at: &str) -> Result<(), GenerateError> {
        let k = |s: &str| format!("{at}.{s}");
        if !(1..=8).contains(&self.plies) {
            return Err(bad(&k("plies"), self.plies, "must be in 1..=8"));
        }
        in_range(&k("ply_twist"), self.ply_twist, -1000.0, 1000.0)?;
        in_range(&k("fiber_twist"), self.fiber_twist, -1000.0, 1000.0)?;
        if let Some(n) = self.fibers_per_ply
            && !(1..=10_000).contains(&n)
        {
            return Err(bad(&k("fibers_per_ply"), n, "must be in 1..=10000"));
        }
        in_range(&k("packing"), self.packing, 0.01, 0.9)?;
        for (i, e) in self.ply_ellipse.iter().enumerate() {
            in_range(&format!("{at}.ply_ellipse[{i}]"), *e, 0.2, 3.0)?;
        }
        in_range(&k("density_epsilon"), self.density_epsilon, 0.0, 0.5)?;
        in_range(&k("density_beta"), self.density_beta, 0.0, 20.0)?;
        in_range(&k("migration_rmin"), self.migration_rmin, 0.0, 1.0)?;
        in_range(&k("migration_rmax"), self.migration_rmax, self.migration_rmin, 2.0)?;
        if self.migration_period != 0.0 {
            in_range(&k("migration_period"), self.migration_period, 1e-3, 1000.0)?;
        }
        let f = &self.flyaways;
        in_range(&k("flyaways.hair_density"), f.hair_density, 0.0, 1e4)?;
        in_range(&k("flyaways.hair_rmin"), f.hair_rmin, 0.0, 1.5)?;
        in_range(&k("flyaways.hair_rspan"), f.hair_rspan, 0.0, 20.0)?;
        in_range(&k("flyaways.hair_zspan"), f.hair_zspan, 0.0, 100.0)?;
        in_range(&k("flyaways.hair_theta_span"), f.hair_theta_span, 0.0, std::f32::consts::TAU)?;
        in_range(&k("flyaways.loop_probability"), f.loop_probability, 0.0, 1.0)?;
        in_range(&k("flyaways.loop_rmax"), f.loop_rmax, 0.0, 20.0)?;
        if f.loop_probability > 0.0 && self.migration_period == 0.0 {
            return Err(bad(&k("flyaways.loop_probability"), f.loop_probability, "loops need fiber migration (migration_period > 0)"));
        }
        Ok(())
    }
}

impl FeltParams {
    fn validate(&self) -> Result<(), GenerateError> {
        in_range("fabric.thickness", self.thickness, 1e-3, 100.0)?;
        in_range("fabric.packing", self.packing, 0.01, 0.8)?;
        in_range("fabric.fiber_length", self.fiber_length, 1e-3, 1000.0)?;
        in_range("fabric.curl", self.curl, 0.0, 50.0)?;
        in_range("fabric.tilt", self.tilt, 0.0, 1.5)?;
        colors("fabric.colors", &self.colors)?;
        in_range("fabric.hair_density", self.hair_density, 0.0, 1e5)?;
        in_range("fabric.hair_length", self.hair_length, 0.0, 100.0)?;
        in_range("fabric.hair_elevation", self.hair_elevation, 0.0, 1.5707964)?;
        in_range("fabric.loop_density", self.loop_density, 0.0, 1e5)?;
        in_range("fabric.loop_height", self.loop_height, 0.0, 100.0)?;
        non_negative("fabric.loop_span", self.loop_span)
    }
}

impl GeneratorParams {
    /// Sets one parameter from `key=value` (TOML value syntax; a bare word is a
    /// string): `fabric.yarn.plies=3`, `fabric.warp_colors=[[0.8,0.1,0.1]]`,
    /// `fabric.pattern=satin`.
    pub fn set(&mut self, assignment: &str) -> Result<(), GenerateError> {
        let (key, value) = assignment.split_once('=').ok_or_else(|| bad(assignment, "", "expected key=value"))?;
        let (key, value) = (key.trim(), value.trim());
        let parsed: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {value}")) {
            Ok(mut t) => t.remove("v").unwrap_or(toml::Value::String(value.to_string())),
            Err(_) => toml::Value::String(value.to_string()),
        };
        let mut root = toml::Value::try_from(&*self).map_err(|e| bad(key, value, &format!("cannot serialize parameters: {e}")))?;
        let mut node = &mut root;
        let parts: Vec<&str> = key.split('.').collect();
        for (i, part) in parts.iter().enumerate() {
            let table = node.as_table_mut().ok_or_else(|| bad(key, value, &format!("'{}' is not a table", parts[..i].join("."))))?;
            if i + 1 == parts.len() {
                table.insert(part.to_string(), parsed.clone());
                break;
            }
            node = table.get_mut(*part).ok_or_else(|| bad(key, value, &format!("no parameter '{}'", parts[..=i].join("."))))?;
        }
        *self = root.try_into().map_err(|e: toml::de::Error| bad(key, value, e.message()))?;
        Ok(())
    }

    /// Merges a (partial) parameter table over these parameters.
    pub fn merge(&mut self, table: &toml::Table) -> Result<(), GenerateError> {
        fn merge_into(dst: &mut toml::Table, src: &toml::Table) {
            for (k, v) in src {
                match (dst.get_mut(k), v) {
                    // A table of another kind (woven → felt) replaces the old one whole.
                    (Some(toml::Value::Table(d)), toml::Value::Table(s)) if s.get("kind").is_none_or(|kind| d.get("kind") == Some(kind)) => merge_into(d, s),
                    _ => {
                        dst.insert(k.clone(), v.clone());
                    }
                }
            }
        }
        let mut root = toml::Table::try_from(&*self).map_err(|e| bad("(parameters)", "", &e.to_string()))?;
        merge_into(&mut root, table);
        *self = toml::Value::Table(root).try_into().map_err(|e: toml::de::Error| bad("(parameters)", "", e.message()))?;
        Ok(())
    }

    /// The parameters as a TOML table (floats written as their shortest f32 text, so
    /// 0.42 reads 0.42, not 0.41999998688697815).
    pub fn to_table(&self) -> toml::Table {
        let mut t = toml::Table::try_from(self).unwrap_or_default();
        t.iter_mut().for_each(|(_, v)| shorten_floats(v));
        t
    }
}

/// Rewrites f64 values that came from f32 with the f32's shortest decimal text.
pub fn shorten_floats(v: &mut toml::Value) {
    match v {
        toml::Value::Float(f) => {
            if let Ok(g) = (*f as f32).to_string().parse::<f64>() {
                *f = g;
            }
        }
        toml::Value::Array(a) => a.iter_mut().for_each(shorten_floats),
        toml::Value::Table(t) => t.iter_mut().for_each(|(_, v)| shorten_floats(v)),
        _ => {}
    }
}
