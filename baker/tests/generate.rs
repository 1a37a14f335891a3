//! Invariants of generated fabrics: value ranges, unit orientations, seamless tiling
//! measured across the wrap seam, flyaways above the main surface, a real surface
//! under them, and bit-identical output for a seed whatever the thread count.

use fabric_baker::generate::{GeneratorParams, Preset, generate};
use fabric_baker::volume::stats::scan_surface;
use fabric_baker::volume::{FabricVolume, MaterialOverrides, load_fabric, save_fabric};

/// Small enough for tests (≈0.1–0.4 s each), large enough that fibers span ≥ 1.5 voxels.
const DIMS: [usize; 3] = [128, 128, 32];

fn gen_with(preset: Preset, set: &[&str], seed: u64) -> FabricVolume {
    let mut p: GeneratorParams = preset.params();
    for s in set {
        p.set(s).unwrap();
    }
    generate(&p, DIMS, seed).unwrap()
}

fn density(v: &FabricVolume, x: usize, y: usize, z: usize) -> f64 {
    v.voxel(x, y, z).density() as f64
}

/// Mean |ρ(a) − ρ(b)| between two x-columns-planes (all y, z).
fn plane_diff_x(v: &FabricVolume, a: usize, b: usize) -> f64 {
    let [_, ny, nz] = v.dims();
    let mut s = 0.0;
    for z in 0..nz {
        for y in 0..ny {
            s += (density(v, a, y, z) - density(v, b, y, z)).abs();
        }
    }
    s / (ny * nz) as f64
}

fn plane_diff_y(v: &FabricVolume, a: usize, b: usize) -> f64 {
    let [nx, _, nz] = v.dims();
    let mut s = 0.0;
    for z in 0..nz {
        for x in 0..nx {
            s += (density(v, x, a, z) - density(v, x, b, z)).abs();
        }
    }
    s / (nx * nz) as f64
}

#[test]
fn every_preset_has_valid_values_and_tiles_seamlessly() {
    for preset in Preset::ALL {
        let v = gen_with(preset, &[], 1);
        let [nx, ny, _] = v.dims();
        let mut filled = 0usize;
        for vox in v.voxels().iter().filter(|v| !v.is_empty()) {
            filled += 1;
            let (rho, a, w) = (vox.density(), vox.albedo(), vox.orientation());
            assert!(rho > 0.0 && rho <= 1.0, "{preset}: density {rho}");
            assert!(a.min_element() >= 0.0 && a.max_element() <= 1.0, "{preset}: albedo {a}");
            assert!((w.length() - 1.0).abs() < 1e-5, "{preset}: orientation {w}");
        }
        let fraction = filled as f64 / v.voxels().len() as f64;
        assert!((0.1..0.7).contains(&fraction), "{preset}: filled fraction {fraction}");

        // Seamless tiling: the density change across the wrap seam (last plane → first)
        // is like the change between any two neighbouring planes inside the tile. A
        // broken seam (unrelated planes) differs several times more; the check below
        // shows the measure sees that.
        for (diff, n, axis) in [(plane_diff_x as fn(&FabricVolume, usize, usize) -> f64, nx, "x"), (plane_diff_y, ny, "y")] {
            let inner: Vec<f64> = (0..n - 1).map(|i| diff(&v, i, i + 1)).collect();
            let mean = inner.iter().sum::<f64>() / inner.len() as f64;
            let max = inner.iter().cloned().fold(0.0, f64::max);
            let seam = diff(&v, n - 1, 0);
            // Planes a quarter tile or more apart stand for a broken seam.
            let unrelated = [n / 4, n / 2 - 3, 3 * n / 4 + 1].iter().map(|&d| diff(&v, n - 1, d)).sum::<f64>() / 3.0;
            eprintln!("{preset} {axis}: seam {seam:.4}, neighbours mean {mean:.4} max {max:.4}, unrelated planes {unrelated:.4}");
            assert!(seam <= 1.25 * mean && seam <= max, "{preset}: seam in {axis} {seam:.4} vs neighbours mean {mean:.4} max {max:.4}");
            assert!(unrelated > 1.4 * mean, "{preset}: the seam measure cannot tell a broken seam ({unrelated:.4} vs {mean:.4})");
        }
    }
}

#[test]
fn flyaways_stand_above_a_real_surface() {
    // Ground truth for flyaways: the same seed with hairs and loops switched off gives the
    // same body fibers (random streams are keyed per fiber), so what only the full volume
    // fills is flyaway.
    let off: &[(Preset, &[&str])] = &[
        (Preset::Twill, &["fabric.yarn.flyaways.hair_density=0", "fabric.yarn.flyaways.loop_probability=0"]),
        (Preset::Satin, &["fabric.yarn.flyaways.hair_density=0", "fabric.yarn.flyaways.loop_probability=0"]),
        (Preset::Plain, &["fabric.yarn.flyaways.hair_density=0", "fabric.yarn.flyaways.loop_probability=0"]),
        (Preset::Felt, &["fabric.hair_density=0", "fabric.loop_density=0"]),
    ];
    for (preset, switches) in off {
        let full = gen_with(*preset, &[], 3);
        let body = gen_with(*preset, switches, 3);
        let [nx, ny, nz] = full.dims();
        // The body alone has a surface: columns scanned from the top meet a run thicker
        // than a fiber (the next stage's h0) almost everywhere.
        let scan = scan_surface(&body, 3);
        let covered = scan.surface_columns as f64 / (nx * ny) as f64;
        assert!(covered > 0.85, "{preset}: only {covered:.3} of columns have a surface");
        // Flyaway voxels exist, and most of them lie above that surface.
        let (mut flyaway, mut above) = (0usize, 0usize);
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    if !full.voxel(x, y, z).is_empty() && body.voxel(x, y, z).is_empty() {
                        flyaway += 1;
                        let h0 = scan.heights[x + nx * y] as usize;
                        above += usize::from(h0 > 0 && z >= h0);
                    }
                }
            }
        }
        let share = flyaway as f64 / full.voxels().iter().filter(|v| !v.is_empty()).count() as f64;
        assert!(share > 0.003, "{preset}: flyaway voxels are only {share:.4} of the filled ones");
        let above_share = above as f64 / flyaway as f64;
        eprintln!("{preset}: surface in {covered:.3} of columns; {flyaway} flyaway voxels ({share:.4} of filled), {above_share:.3} above the surface");
        // Hairs leave yarns on every side (and felt hairs are rooted just below the top),
        // so not all are above; felt's are nearly all.
        let expect = if *preset == Preset::Felt { 0.6 } else { 0.2 };
        assert!(above_share > expect, "{preset}: only {above_share:.3} of {flyaway} flyaway voxels are above the surface");
    }
    // Silk charmeuse has no flyaways: switching them off changes nothing.
    let silk = gen_with(Preset::Silk, &[], 3);
    let silk_off = gen_with(Preset::Silk, &["fabric.yarn.flyaways.hair_density=0", "fabric.yarn.flyaways.loop_probability=0"], 3);
    assert!(silk.voxels() == silk_off.voxels());
}

#[test]
fn a_seed_gives_bit_identical_volumes_for_any_thread_count() {
    let params = Preset::Twill.params();
    let run = |threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| generate(&params, [96, 80, 24], seed).unwrap())
    };
    let one = run(1, 7);
    let two = run(2, 7);
    let three = run(3, 7);
    assert!(one.voxels() == two.voxels() && two.voxels() == three.voxels(), "thread count changed the volume");
    assert!(run(2, 8).voxels() != one.voxels(), "another seed must give another fabric");

    // And the files are byte-identical.
    let base = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("generate_determinism");
    let (a, b) = (base.join("a"), base.join("b"));
    save_fabric(&one, &a).unwrap();
    save_fabric(&three, &b).unwrap();
    for f in ["density.vol", "albedo.vol", "orientation.vol", "material.toml"] {
        assert!(std::fs::read(a.join(f)).unwrap() == std::fs::read(b.join(f)).unwrap(), "{f} differs");
    }
    // What was written loads back as the same voxels' values.
    let back = load_fabric(&a, &MaterialOverrides::default()).unwrap();
    for (p, q) in one.voxels().iter().zip(back.voxels()) {
        assert_eq!((p.density, p.albedo), (q.density, q.albedo));
    }
}

#[test]
fn bad_parameters_and_sizes_are_errors() {
    let p = Preset::Twill.params();
    for (dims, msg) in [([0, 64, 16], "at least one cell"), ([1 << 17, 4, 4], "exceeds")] {
        let e = generate(&p, dims, 1).unwrap_err().to_string();
        assert!(e.contains(msg), "{e}");
    }
    let mut q = p.clone();
    q.set("fiber.diameter=0.0001").unwrap();
    let e = generate(&q, [64, 64, 16], 1).unwrap_err().to_string();
    assert!(e.contains("0.25 voxel"), "{e}");
    let mut q = p.clone();
    q.set("fabric.cover=-1").unwrap();
    assert!(generate(&q, [64, 64, 16], 1).unwrap_err().to_string().contains("fabric.cover"));
    let mut q = p;
    q.set("fabric.yarn.fibers_per_ply=10000").unwrap();
    q.set("voxel_size=0.0005").unwrap();
    let e = generate(&q, [4096, 4096, 32], 1).unwrap_err().to_string();
    assert!(e.contains("segments"), "{e}");
    // Values that once overflowed a count or asked for tens of GB are refused by name.
    for (preset, set) in [(Preset::Twill, "fabric.yarn.flyaways.hair_density=1e30"), (Preset::Twill, "fabric.warp_spacing=1e-9"), (Preset::Twill, "fabric.yarn.fiber_twist=1e6"), (Preset::Twill, "fabric.yarn.migration_period=1e-7"), (Preset::Felt, "fabric.fiber_length=1e-30"), (Preset::Felt, "fiber.diameter=1e30")] {
        let mut q = preset.params();
        q.set(set).unwrap();
        let key = set.split('=').next().unwrap();
        let e = generate(&q, [16, 16, 8], 1).unwrap_err().to_string();
        assert!(e.contains(key) && e.contains("must be in"), "{set}: {e}");
    }
}
