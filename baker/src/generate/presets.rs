//! Named starting points for the generator. Units: mm. At the default z resolution
//! (48) the voxel comes out at 4–7 µm, so fibers span 2–4 voxels and yarns 20–40.
//!
//! | preset  | structure                     | fibers              | look                         |
//! |---------|-------------------------------|---------------------|------------------------------|
//! | plain   | plain weave, 2-ply cotton     | 12 µm, twisted      | chambray: blue warp, white weft |
//! | twill   | 2/2 twill, singles cotton     | 12 µm, twisted      | denim: indigo warp, ecru weft |
//! | satin   | 5-harness warp-faced satin    | 11 µm, 2-ply, low twist | three colours: rose and gold warps, blue weft |
//! | silk    | 8-harness satin (charmeuse)   | 8 µm filaments, nearly untwisted, no flyaways | champagne, very smooth |
//! | felt    | non-woven matted layer        | 20 µm wool, curly   | red, very hairy              |
//!
//! Albedos are single-scattering albedos (0.5–0.95): multiple scattering makes the
//! fabric look darker than these numbers.

use std::fmt;
use std::str::FromStr;

use super::params::*;

/// A named parameter set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Preset {
    Plain,
    Twill,
    Satin,
    Silk,
    Felt,
}

impl Preset {
    pub const ALL: [Preset; 5] = [Preset::Plain, Preset::Twill, Preset::Satin, Preset::Silk, Preset::Felt];

    pub fn name(self) -> &'static str {
        match self {
            Preset::Plain => "plain",
            Preset::Twill => "twill",
            Preset::Satin => "satin",
            Preset::Silk => "silk",
            Preset::Felt => "felt",
        }
    }

    /// The preset's parameters.
    pub fn params(self) -> GeneratorParams {
        match self {
            Preset::Plain => woven(
                PatternKind::Plain,
                (2, 1, 1),
                (0.14, 0.14),
                0.5,
                vec![[0.42, 0.55, 0.82]],
                vec![[0.90, 0.89, 0.85]],
                cotton_yarn(),
                0.22,
            ),
            Preset::Twill => woven(
                PatternKind::Twill,
                (4, 2, 1),
                (0.14, 0.14),
                0.45,
                vec![[0.22, 0.33, 0.70]],
                vec![[0.88, 0.85, 0.76]],
                singles_yarn(),
                0.22,
            ),
            Preset::Satin => {
                // Sateen: a soft, low-twist two-ply yarn, so the warp floats lie smooth.
                let mut yarn = cotton_yarn();
                yarn.ply_twist = 0.8;
                yarn.fiber_twist = -1.2;
                yarn.flyaways.hair_density = 1.0;
                let mut p = woven(
                    PatternKind::Satin,
                    (5, 1, 2),
                    (0.12, 0.14),
                    0.42,
                    vec![[0.92, 0.50, 0.58], [0.93, 0.78, 0.45]],
                    vec![[0.45, 0.52, 0.88]],
                    yarn,
                    0.15,
                );
                p.fiber.diameter = 0.011;
                if let FabricParams::Woven(w) = &mut p.fabric {
                    w.cover = 1.1;
                    w.crimp_balance = 0.75;
                }
                p
            }
            Preset::Silk => {
                let yarn = YarnParams {
                    plies: 1,
                    ply_twist: 0.0,
                    fiber_twist: 0.3,
                    fibers_per_ply: None,
                    packing: 0.75,
                    ply_ellipse: [1.0, 1.0],
                    density_epsilon: 0.3,
                    density_beta: 0.5,
                    migration_rmin: 0.9,
                    migration_rmax: 1.0,
                    migration_period: 0.0,
                    flyaways: FlyawayParams { hair_density: 0.0, hair_rmin: 0.9, hair_rspan: 0.0, hair_zspan: 0.0, hair_theta_span: 0.0, loop_probability: 0.0, loop_rmax: 1.0 },
                };
                let mut p = woven(PatternKind::Satin, (8, 1, 3), (0.065, 0.08), 0.38, vec![[0.93, 0.86, 0.70]], vec![[0.90, 0.82, 0.66]], yarn, 0.06);
                p.fiber.diameter = 0.008;
                p.fiber.albedo_variation = 0.03;
                (p.headroom, p.footroom) = (0.03, 0.05);
                if let FabricParams::Woven(w) = &mut p.fabric {
                    w.cover = 1.1;
                    w.crimp = 0.9;
                    w.crimp_balance = 0.75;
                }
                p
            }
            Preset::Felt => GeneratorParams {
                voxel_size: None,
                headroom: 0.12,
                footroom: 0.01,
                fiber: FiberParams { diameter: 0.02, albedo_variation: 0.08 },
                material: MaterialSpec { roughness: 0.3, fiber_optical_depth: 2.0 },
                fabric: FabricParams::Felt(FeltParams {
                    thickness: 0.19,
                    packing: 0.4,
                    fiber_length: 1.5,
                    curl: 4.0,
                    tilt: 0.18,
                    colors: vec![[0.85, 0.22, 0.18], [0.80, 0.26, 0.20], [0.90, 0.30, 0.24]],
                    hair_density: 60.0,
                    hair_length: 0.2,
                    hair_elevation: 0.7,
                    loop_density: 25.0,
                    loop_height: 0.06,
                    loop_span: 0.15,
                }),
            },
        }
    }
}

/// Two-ply cotton (Zhao et al. 2016 fit cotton with ply and fiber twist of opposite
/// sign, strong migration and many hairs). The plies are pressed wide (e_B = 1.6) so the
/// flattened yarn keeps most of its width when the plies stand on top of each other.
fn cotton_yarn() -> YarnParams {
    YarnParams {
        plies: 2,
        ply_twist: 1.5,
        fiber_twist: -2.5,
        fibers_per_ply: None,
        packing: 0.7,
        ply_ellipse: [0.8, 1.6],
        density_epsilon: 0.1,
        density_beta: 0.6,
        migration_rmin: 0.5,
        migration_rmax: 1.0,
        migration_period: 0.3,
        flyaways: FlyawayParams { hair_density: 1.5, hair_rmin: 0.9, hair_rspan: 2.5, hair_zspan: 0.15, hair_theta_span: 1.0, loop_probability: 0.04, loop_rmax: 1.8 },
    }
}

/// A ring-spun singles yarn (one ply, as in denim): fibers twisted about the yarn axis.
fn singles_yarn() -> YarnParams {
    // The single ply is the whole yarn, twice a 2-ply's ply radius: hairs and loops
    // reach proportionally less far out (in ply radii) for the same length in mm.
    let mut y = YarnParams { plies: 1, ply_twist: 0.0, fiber_twist: 3.0, ply_ellipse: [1.0, 1.0], ..cotton_yarn() };
    y.flyaways.hair_rspan = 1.4;
    y.flyaways.loop_rmax = 1.4;
    y
}

#[allow(clippy::too_many_arguments)]
fn woven(
    pattern: PatternKind,
    (repeat, over, step): (u32, u32, u32),
    (warp_spacing, weft_spacing): (f32, f32),
    flattening: f32,
    warp_colors: Vec<[f32; 3]>,
    weft_colors: Vec<[f32; 3]>,
    yarn: YarnParams,
    roughness: f32,
) -> GeneratorParams {
    GeneratorParams {
        voxel_size: None,
        headroom: 0.07,
        footroom: 0.02,
        fiber: FiberParams { diameter: 0.012, albedo_variation: 0.06 },
        material: MaterialSpec { roughness, fiber_optical_depth: 2.0 },
        fabric: FabricParams::Woven(WovenParams { pattern, repeat, over, step, warp_spacing, weft_spacing, cover: 1.05, flattening, crimp: 1.0, crimp_balance: 0.5, warp_colors, weft_colors, yarn }),
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Preset {
    type Err = String;
    fn from_str(s: &str) -> Result<Preset, String> {
        Preset::ALL.into_iter().find(|p| p.name() == s).ok_or_else(|| format!("unknown preset '{s}' (known: plain, twill, satin, silk, felt)"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_overridable() {
        for p in Preset::ALL {
            p.params().validate().unwrap_or_else(|e| panic!("{p}: {e}"));
            assert_eq!(p.name().parse::<Preset>().unwrap(), p);
        }
        assert!("tweed".parse::<Preset>().unwrap_err().contains("plain, twill"));
        let mut t = Preset::Twill.params();
        t.set("fabric.yarn.plies=3").unwrap();
        t.set("fabric.warp_colors = [[0.5, 0.5, 0.5], [0.9, 0.1, 0.1]]").unwrap();
        t.set("fabric.pattern=satin").unwrap();
        t.set("voxel_size=0.004").unwrap();
        let FabricParams::Woven(w) = &t.fabric else { panic!() };
        assert_eq!((w.yarn.plies, w.warp_colors.len(), w.pattern, t.voxel_size), (3, 2, PatternKind::Satin, Some(0.004)));
        // Wrong keys, types and values are errors naming the key.
        for (bad, key) in [("fabric.yarn.plys=3", "plys"), ("fabric.yarn.plies=three", "plies"), ("nothing.here=1", "nothing"), ("fiber", "fiber")] {
            let e = t.set(bad).unwrap_err().to_string();
            assert!(e.contains(key), "{bad}: {e}");
        }
        let mut t = Preset::Twill.params();
        t.set("fabric.repeat=7").unwrap();
        t.set("fabric.over=7").unwrap();
        assert!(t.validate().unwrap_err().to_string().contains("fabric.over"));
        let mut s = Preset::Satin.params();
        s.set("fabric.step=1").unwrap();
        assert!(s.validate().unwrap_err().to_string().contains("coprime"));
        // A parameter table round-trips through TOML (what material.toml records).
        let f = Preset::Felt.params();
        let mut g = Preset::Plain.params();
        g.merge(&f.to_table()).unwrap();
        assert_eq!(g, f);
    }
}
