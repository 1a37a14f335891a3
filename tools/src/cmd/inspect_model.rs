//! `fabric inspect MODEL.hyb`: the sections, levels, sizes and parameter statistics of
//! a hybrid model file, as text or JSON. (The lead wires it into `fabric inspect`, next
//! to the inspection of `.vol` volumes.)

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use fabric_runtime::hybrid::format::FileInfo;
use fabric_runtime::hybrid::stats::Range;

/// Prints what `path` holds; `json` prints the [`FileInfo`] as JSON instead of text.
pub fn run(path: &Path, json: bool) -> Result<()> {
    let info = inspect_file(path)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&info).context("cannot serialize the report")?);
    } else {
        print!("{}", text_report(path, &info));
    }
    Ok(())
}

/// Reads and checks the file (memory-mapped), and describes it.
pub fn inspect_file(path: &Path) -> Result<FileInfo> {
    fabric_runtime::hybrid::format::inspect_file(path).context("not a valid hybrid model")
}

fn range(r: &Range) -> String {
    if r.count == 0 {
        return "-".into();
    }
    format!("{:.4} / {:.4} / {:.4}", r.min, r.mean, r.max)
}

fn mib(bytes: u64) -> String {
    format!("{:.2} MiB", bytes as f64 / (1024.0 * 1024.0))
}

/// The text report.
pub fn text_report(path: &Path, info: &FileInfo) -> String {
    let m = &info.model;
    let mut s = String::new();
    let _ = writeln!(s, "{}: hybrid model, format {}.{}, {} bytes ({})", path.display(), info.version.0, info.version.1, info.file_size, mib(info.file_size));
    let _ = writeln!(s, "  level 0: {}x{} texels, {} levels; BRDF reading: {}; fitted with height-field shadowing: {}; volumetric factor: {}; diffuse law: {}; flyaway lobes: {}; flyaways shadow the surface: {}", m.width, m.height, m.levels, m.reading, m.fitted_with_shadowing, m.volumetric, m.diffuse, m.fiber_lobes, m.flyaway_shadow);
    let _ = writeln!(s, "  tile: origin ({}, {}), size {} x {}, top plane z = {}, height scale {}, flyaway voxel depth {}", m.tile_origin[0], m.tile_origin[1], m.tile_size[0], m.tile_size[1], m.top_z, m.height_scale, m.voxel_depth);
    let _ = writeln!(s, "  depth below the top plane (min / mean / max): {}", range(&m.depth));
    let b = m.source_bbox;
    let _ = writeln!(s, "  source: bbox ({}, {}, {}) .. ({}, {}, {}), {}x{}x{} voxels; bake seed {}", b[0], b[1], b[2], b[3], b[4], b[5], m.source_dims[0], m.source_dims[1], m.source_dims[2], m.seed);
    if !m.note.is_empty() {
        let _ = writeln!(s, "  note: {}", m.note);
    }
    let _ = writeln!(s, "\nsections:");
    let _ = writeln!(s, "  {:<26} {:>5} {:>10} {:>10} {:>10}", "kind", "level", "offset", "bytes", "crc32");
    for sec in &info.sections {
        let _ = writeln!(s, "  {:<26} {:>5} {:>10} {:>10}   {:08x}  {}", sec.kind, sec.level, sec.offset, sec.length, sec.crc32, if sec.optional { "optional" } else { "" });
    }
    let _ = writeln!(s, "\nlevels (parameters as min / mean / max over texels):");
    for l in &m.level_stats {
        let encoding = match l.clusters {
            Some(k) => format!("clustered, {k} clusters"),
            None => l.encoding.to_string(),
        };
        let texels = (l.width as u64 * l.height as u64).max(1);
        let _ = writeln!(
            s,
            "  level {}: {}x{}, {encoding}, {} lobes stored, lobes/texel {}; surface {} ({:.1} B/texel){}",
            l.level,
            l.width,
            l.height,
            l.lobes_stored,
            range(&l.lobes_per_texel),
            mib(l.surface_bytes),
            l.surface_bytes as f64 / texels as f64,
            l.fit_error.map(|e| format!("; fit error {e:.4}")).unwrap_or_default()
        );
        let _ = writeln!(s, "    k_d (luminance) {}   eta {}   a {}", range(&l.kd_luminance), range(&l.eta), range(&l.a));
        let _ = writeln!(s, "    k (luminance) {}   beta {}   gamma {} (off for {:.1}% of lobes)", range(&l.k_luminance), range(&l.beta), range(&l.gamma), 100.0 * l.gamma_off_fraction);
        if l.transmission_bytes > 0 {
            let _ = writeln!(s, "    transmission: one term per texel (BSDF); {}", mib(l.transmission_bytes));
            if let (Some(o), Some(f)) = (&l.openness, l.open_texels) {
                let _ = writeln!(s, "    openness straight down (the gaps between yarns): {} over texels, {:.1}% of texels open", range(o), 100.0 * f);
            }
            if let Some(m) = l.transmission_gradient_median {
                let _ = writeln!(s, "    transmission visibility per texel (format 1.16): gradient |g| median {m:.2} (counted in the transmission's bytes)");
            }
        }
        if let Some(m) = l.gradient_median {
            let _ = writeln!(s, "    visibility gradient per texel (format 1.12): |g| median {m:.2}; {}", mib(l.gradient_bytes));
        }
        if let Some(m) = l.curvature_median {
            let _ = writeln!(s, "    visibility curvature per texel (format 1.15): |q| median {m:.2}; {}", mib(l.curvature_bytes));
        }
        if l.flyaway_nodes > 0 || l.flyaway_bytes > 0 {
            let _ = writeln!(s, "    flyaways: {} voxels in {} columns, longest list {}, alpha {}; {}", l.flyaway_nodes, l.flyaway_columns, l.flyaway_longest_list, range(&l.flyaway_alpha), mib(l.flyaway_bytes));
        }
        if let Some(g) = &l.flyaway_path_gain {
            let _ = writeln!(s, "    flyaway path gain (opacity exponent at 0°, 10°, … 80°): {}", g.iter().map(|g| format!("{g:.2}")).collect::<Vec<_>>().join(" "));
        }
    }
    let _ = writeln!(s, "\npayload: {} (height field {})", mib(m.payload_bytes), mib(m.height_bytes));
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use fabric_runtime::hybrid::{examples, format};

    #[test]
    fn reports_a_model_and_rejects_a_corrupt_file_by_name() {
        let dir = std::env::temp_dir().join(format!("fabric-inspect-{}", std::process::id()));
        let path = dir.join("sample.hyb");
        format::write_file(&examples::sample_model(), &path).unwrap();
        let info = inspect_file(&path).unwrap();
        let text = text_report(&path, &info);
        assert!(text.contains("12x10 texels, 4 levels") && text.contains("clustered, 3 clusters") && text.contains("FLYAWAY_NODES"), "{text}");
        let json: serde_json::Value = serde_json::from_str(&serde_json::to_string(&info).unwrap()).unwrap();
        assert_eq!(json["model"]["level_stats"][0]["flyaway_nodes"], 10);
        run(&path, true).unwrap();
        run(&path, false).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        let n = bytes.len();
        bytes[n - 5] ^= 0xff;
        let bad = dir.join("bad.hyb");
        std::fs::write(&bad, &bytes).unwrap();
        let err = format!("{:#}", run(&bad, false).unwrap_err());
        assert!(err.contains("bad.hyb") && err.contains("checksum"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
