//! `fabric render MODEL.hyb --backend cpu`: the CPU renderer of hybrid models
//! (`fabric_runtime::cpu`). The lead wires it into `fabric render`: flatten
//! [`CpuRenderFlags`] into `RenderArgs` and call [`run`] for `--backend cpu`.

use std::path::Path;

use anyhow::{Context, Result};
use clap::Args;
use fabric_runtime::cpu::{CoarseFilter, CpuRenderOptions, EditMask, Edits, EnvLight, LevelChoice, ShadowMode, render_with_progress};
use fabric_runtime::scene::{ExtractOptions, Light, PrefilteredEnv};
use fabric_runtime::hybrid::format::read_file;
use indicatif::{ProgressBar, ProgressStyle};

use crate::args::{CameraArgs, EnvArgs, LightArgs, OutputArgs};

/// Flags of the CPU backend (the camera, light and output flags are the shared ones).
#[derive(Args, Clone, Debug)]
pub struct CpuRenderFlags {
    /// Level of the mip chain: "auto" (from each pixel's footprint, adjacent levels
    /// blended), "nearest" (the nearest level, no blending) or a level number.
    #[arg(long, default_value = "auto", value_parser = parse_level)]
    pub level: LevelFlag,
    /// Added to log2 of the footprint with --level auto (positive: coarser).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub level_bias: f32,
    /// Repeat the tile forever in x and y (matches `fabric reference --periodic`).
    #[arg(long)]
    pub periodic: bool,
    /// Height-field shadowing: "model" (as the model was fitted), "on" or "off".
    #[arg(long, default_value = "model", value_parser = ["model", "on", "off"])]
    pub shadows: String,
    /// s×s camera rays per pixel on a regular grid (1..=16); at automatic levels each
    /// filters its own sub-pixel, so far views converge on the supersampled level 0 (2×2:
    /// the presets' far views about halved, baker/PREFILTER_MEASUREMENTS.md).
    #[arg(long, default_value_t = 1)]
    pub supersample: u32,
    /// Height-field traversal steps per ray before giving up.
    #[arg(long, default_value_t = 4096)]
    pub max_steps: u32,
    /// Skip the flyaway fibers (the surface alone).
    #[arg(long)]
    pub no_flyaways: bool,
    /// March the height field only down to each pixel's level: fewer steps far away,
    /// relief finer than a pixel flattened (off: exact at every distance).
    #[arg(long)]
    pub coarse_relief: bool,
    /// How coarse levels are filtered: "split-shaded" (the default: a 2×2 grid of
    /// lookups one level finer, closer to the pixel's box, where 2×2 parallel rays land;
    /// the flyaways' coverage and the lights' light from a 4×4 grid of rays one level
    /// finer, an environment's SG part from the 2×2 rays),
    /// "split" (the flyaways' light from the 2×2 rays, spread over the 4×4 grid's
    /// coverage marched unshaded: cheaper, far views up to 1.6 points worse),
    /// "box" (the flyaways' coverage from the 2×2 rays too: far views summed 20% higher
    /// than split's, at half a distant frame's time under one light,
    /// runtime/GPU_MEASUREMENTS.md), "fine" (the flyaways along the 4×4 grid and level
    /// 0's lookups where those rays land) or "bilinear" (one lookup per anisotropic tap:
    /// cheaper far away).
    #[arg(long, default_value = "split-shaded", value_parser = clap::builder::PossibleValuesParser::new(CoarseFilter::NAMES.map(|(n, _)| n)))]
    pub coarse_filter: String,
    /// Edit: multiply the albedo and every lobe's strength (V or R,G,B, linear).
    #[arg(long, value_parser = crate::args::parse_rgb, default_value = "1")]
    pub tint: glam::Vec3,
    /// Edit: multiply every lobe's widths β and γ (> 1: rougher, < 1: shinier).
    #[arg(long, default_value_t = 1.0)]
    pub roughness_scale: f32,
    /// Edit: rotate the surface's fiber tangents about their normals (degrees).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub tangent_rotation: f32,
    /// Apply the edits only where this grey image is bright (PNG or EXR over one tile
    /// seen from above, row 0 at +y; value = its red channel, 0..1).
    #[arg(long)]
    pub edit_mask: Option<std::path::PathBuf>,
}

/// `--level auto` or `--level N`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LevelFlag {
    Auto,
    Nearest,
    Fixed(u32),
}

fn parse_level(s: &str) -> Result<LevelFlag, String> {
    if s == "auto" {
        return Ok(LevelFlag::Auto);
    }
    if s == "nearest" {
        return Ok(LevelFlag::Nearest);
    }
    s.parse().map(LevelFlag::Fixed).map_err(|_| format!("expected 'auto', 'nearest' or a level number, got '{s}'"))
}

impl CpuRenderFlags {
    pub fn options(&self) -> Result<CpuRenderOptions> {
        let mask = match &self.edit_mask {
            Some(path) => {
                let img = fabric_runtime::image::Image::read(path, 1.0).with_context(|| format!("cannot read the edit mask {}", path.display()))?;
                let mask = EditMask::new(img.width, img.height, img.pixels.iter().map(|p| p.x).collect()).map_err(anyhow::Error::msg)?;
                Some(std::sync::Arc::new(mask))
            }
            None => None,
        };
        let edits = Edits { tint: self.tint, roughness_scale: self.roughness_scale, tangent_rotation: self.tangent_rotation.to_radians(), mask };
        edits.validate().map_err(|e| anyhow::anyhow!("invalid edit: {e}"))?;
        Ok(CpuRenderOptions {
            level: match self.level {
                LevelFlag::Auto => LevelChoice::Auto { bias: self.level_bias },
                LevelFlag::Nearest => LevelChoice::Nearest { bias: self.level_bias },
                LevelFlag::Fixed(n) => LevelChoice::Fixed(n),
            },
            periodic: self.periodic,
            shadows: match self.shadows.as_str() {
                "on" => ShadowMode::On,
                "off" => ShadowMode::Off,
                _ => ShadowMode::FromModel,
            },
            supersampling: self.supersample,
            max_steps: self.max_steps,
            flyaways: !self.no_flyaways,
            coarse_relief: self.coarse_relief,
            // clap's value parser admits nothing else.
            coarse_filter: CoarseFilter::from_name(&self.coarse_filter).unwrap_or_default(),
            edits,
            ..Default::default()
        })
    }
}

/// The lights of a render and, with `--envmap`, the prefiltered map in `options`: with
/// a map the delta light is there only when a light flag asks for it (as `fabric
/// reference`); the map's compact sources join the lights when the render runs.
pub fn lights_and_env(light: &LightArgs, env: &EnvArgs, options: &mut CpuRenderOptions) -> Result<Vec<Light>> {
    let map = env.env_map()?;
    let lights: Vec<Light> = if map.is_none() || light.given() { vec![light.light()?] } else { Vec::new() };
    if let Some(map) = map {
        let t = std::time::Instant::now();
        let prefiltered = PrefilteredEnv::with_lights(&map, ExtractOptions::default())?;
        println!(
            "environment {} ({}x{}): {} source(s) shaded as directional lights{}, the rest prefiltered into {} SG levels (σ {:.3}–{:.2} rad) in {:.2?}",
            map.name().display(),
            map.width(),
            map.height(),
            prefiltered.lights.len(),
            prefiltered.lights.iter().map(|l| match l { Light::Directional { dir_to_light, irradiance } => format!(" [toward {:.3},{:.3},{:.3}, irradiance {:.3}]", dir_to_light.x, dir_to_light.y, dir_to_light.z, irradiance.dot(glam::Vec3::ONE) / 3.0), _ => String::new() }).collect::<String>(),
            prefiltered.levels.len(),
            prefiltered.sigma0,
            prefiltered.sigma_max(),
            t.elapsed()
        );
        options.env = Some(EnvLight { background: !env.no_background, ..EnvLight::new(prefiltered) });
    }
    Ok(lights)
}

/// Renders `model_path` with the CPU renderer and writes the image.
pub fn run(model_path: &Path, camera: &CameraArgs, light: &LightArgs, env: &EnvArgs, output: &OutputArgs, flags: &CpuRenderFlags) -> Result<()> {
    output.validate()?;
    let model = read_file(model_path)?;
    // The default framing and --view-angles aim at the model's box: the tile's x–y box
    // from the top plane down through the depth range, i.e. the source volume's box.
    let camera = camera.camera(model.bounds())?;
    let mut options = flags.options()?;
    let lights = lights_and_env(light, env, &mut options)?;
    if options.shadows == ShadowMode::FromModel {
        println!("shadowing: {} (as the model was fitted)", if model.meta.fitted_with_shadowing { "on" } else { "off" });
    } else if (options.shadows == ShadowMode::On) != model.meta.fitted_with_shadowing {
        println!("note: the model was fitted {} height-field shadowing; rendering {} it", if model.meta.fitted_with_shadowing { "with" } else { "without" }, if options.shadows == ShadowMode::On { "with" } else { "without" });
    }
    let bar = ProgressBar::new(camera.height as u64);
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} rows, {elapsed} (eta {eta})").unwrap_or_else(|_| ProgressStyle::default_bar()));
    let start = std::time::Instant::now();
    let (image, stats) = render_with_progress(&model, &camera, &lights, &options, &|| bar.inc(1)).with_context(|| format!("cannot render {}", model_path.display()))?;
    let elapsed = start.elapsed();
    bar.finish_and_clear();
    image.write(&output.out, output.exposure)?;
    let rays = stats.pixels * (options.supersampling as u64).pow(2);
    println!(
        "{}: {}x{} on the CPU ({} threads) in {:.2?}, {:.2} Mrays/s; {} pixels on the tile, {} on the surface, {} with flyaways; pixels per level {:?}",
        model_path.display(),
        camera.width,
        camera.height,
        rayon::current_num_threads(),
        elapsed,
        rays as f64 / elapsed.as_secs_f64().max(1e-9) / 1e6,
        stats.tile_pixels,
        stats.surface_pixels,
        stats.flyaway_pixels,
        stats.level_pixels
    );
    super::render::warn_if_tile_unseen(stats.tile_pixels);
    super::render::warn_if_lit_from_below(&model, &lights, options.env.is_some());
    if stats.step_limited_pixels > 0 || stats.step_limited_shadow_rays > 0 {
        println!("warning: {} camera rays and {} shadow rays ran out of --max-steps {}", stats.step_limited_pixels, stats.step_limited_shadow_rays, options.max_steps);
    }
    println!("wrote {}", output.out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use fabric_runtime::hybrid::{examples, format};

    #[test]
    fn renders_a_model_file_and_reports_bad_flags() {
        let dir = std::env::temp_dir().join(format!("fabric-render-cpu-{}", std::process::id()));
        let model = dir.join("m.hyb");
        format::write_file(&examples::sample_model(), &model).unwrap();
        let camera = CameraArgs { view_angles: Some((30.0, -90.0)), size: (32, 24), up: glam::Vec3::Z, ..Default::default() };
        let light = LightArgs { light_angles: Some((20.0, 40.0)), irradiance: glam::Vec3::ONE, intensity: glam::Vec3::ONE, ..Default::default() };
        let output = OutputArgs { out: dir.join("out.exr"), exposure: 1.0 };
        let flags = CpuRenderFlags { level: LevelFlag::Auto, level_bias: 0.0, periodic: true, shadows: "on".into(), supersample: 1, max_steps: 4096, no_flyaways: false, coarse_relief: false, coarse_filter: "split-shaded".into(), tint: glam::Vec3::ONE, roughness_scale: 1.0, tangent_rotation: 0.0, edit_mask: None };
        run(&model, &camera, &light, &EnvArgs::default(), &output, &flags).unwrap();
        let image = fabric_runtime::image::Image::read(&output.out, 1.0).unwrap();
        assert_eq!((image.width, image.height), (32, 24));
        assert!(image.mean() > 0.0);
        let err = run(&model, &camera, &light, &EnvArgs::default(), &output, &CpuRenderFlags { level: LevelFlag::Fixed(9), ..flags.clone() }).unwrap_err();
        assert!(format!("{err:#}").contains("level 9 does not exist"), "{err:#}");
        let err = run(&model, &camera, &light, &EnvArgs::default(), &output, &CpuRenderFlags { roughness_scale: -1.0, ..flags.clone() }).unwrap_err();
        assert!(format!("{err:#}").contains("roughness scale"), "{err:#}");
        let err = run(&model, &camera, &light, &EnvArgs::default(), &output, &CpuRenderFlags { edit_mask: Some(dir.join("no-mask.png")), ..flags.clone() }).unwrap_err();
        assert!(format!("{err:#}").contains("edit mask"), "{err:#}");
        let err = run(&dir.join("missing.hyb"), &camera, &light, &EnvArgs::default(), &output, &flags).unwrap_err();
        assert!(format!("{err:#}").contains("missing.hyb"), "{err:#}");
        assert_eq!(parse_level("auto"), Ok(LevelFlag::Auto));
        assert_eq!(parse_level("3"), Ok(LevelFlag::Fixed(3)));
        assert!(parse_level("-1").is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
