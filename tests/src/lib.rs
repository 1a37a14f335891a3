//! Support for the workspace-level tests: screenshot regression against golden PNGs
//! with the FLIP metric (the wgpu test-suite pattern).
//!
//! - Goldens live in `tests/goldens/NAME.png` (8-bit sRGB of exposure · L, the PNG
//!   mapping of DESIGN.md §8) and change only when `UPDATE_GOLDENS=1` is set; a missing
//!   golden is a failure, never silently written.
//! - On failure the actual image and a FLIP difference image (magma scale) are
//!   written to `target/test-output/NAME-actual.png` and `NAME-difference.png`.

use std::path::PathBuf;

use fabric_runtime::image::Image;
use fabric_runtime::metrics::flip_srgb8;

/// How much FLIP error a screenshot may have, with the reason for the bound.
///
/// `mean` catches a change spread over the image; `outliers` a local one (a patch of
/// missing or wrong pixels). The outlier bound leaves room for the isolated pixels whose
/// hit lands on another texel from one driver to another (an ulp of the interpolated
/// position or of a division): 0.23% of a sphere golden's pixels drawn on an NVIDIA
/// H200 against lavapipe's. The weighted 95th percentile used before counted such a
/// handful as a failure (0.15 against 0.05); it is still printed.
#[derive(Clone, Copy, Debug)]
pub struct FlipTolerance {
    /// Bound on the mean per-pixel FLIP error.
    pub mean: f32,
    /// Bound on the fraction of pixels with a FLIP error above [`OUTLIER_FLIP`].
    pub outliers: f32,
}

/// Per-pixel FLIP error above which a pixel is an outlier (plainly visible).
pub const OUTLIER_FLIP: f32 = 0.1;

pub fn goldens_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("goldens")
}

/// Where failing tests leave their images.
pub fn output_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target"));
    target.join("test-output")
}

/// Compares `image` (linear) tone-mapped with `exposure` against `goldens/NAME.png`.
pub fn check_golden(name: &str, image: &Image, exposure: f32, tol: FlipTolerance) -> Result<(), String> {
    let golden_path = goldens_dir().join(format!("{name}.png"));
    let actual = image.to_srgb8(exposure);
    if std::env::var("UPDATE_GOLDENS").as_deref() == Ok("1") {
        image.write(&golden_path, exposure).map_err(|e| e.to_string())?;
        eprintln!("updated golden {}", golden_path.display());
        return Ok(());
    }
    let golden = image::open(&golden_path)
        .map_err(|e| format!("golden {} cannot be read ({e}); create it deliberately with UPDATE_GOLDENS=1", golden_path.display()))?
        .to_rgb8();
    let fail = |msg: String, err_map: Option<Vec<u8>>| {
        let dir = output_dir();
        let _ = std::fs::create_dir_all(&dir);
        let _ = image.write(&dir.join(format!("{name}-actual.png")), exposure);
        if let Some(m) = err_map {
            let _ = image::save_buffer(dir.join(format!("{name}-difference.png")), &m, image.width, image.height, image::ExtendedColorType::Rgb8);
        }
        Err(format!("{msg}; actual and difference images in {}", dir.display()))
    };
    if golden.dimensions() != (image.width, image.height) {
        return fail(format!("{name}: image is {}x{}, golden is {}x{}", image.width, image.height, golden.width(), golden.height()), None);
    }
    let f = flip_srgb8(&actual, golden.as_raw(), image.width, image.height);
    let outliers = f.error_map.iter().filter(|&&e| e > OUTLIER_FLIP).count() as f32 / f.error_map.len().max(1) as f32;
    if f.mean > tol.mean || outliers > tol.outliers {
        return fail(format!("{name}: FLIP mean {:.5} (allowed {}), {:.3}% of pixels above {OUTLIER_FLIP} (allowed {}%; weighted p95 {:.5})", f.mean, tol.mean, 100.0 * outliers, 100.0 * tol.outliers, f.p95), Some(f.error_map_rgb8()));
    }
    eprintln!("{name}: FLIP mean {:.5}, {:.3}% of pixels above {OUTLIER_FLIP} (allowed {}, {}%; weighted p95 {:.5})", f.mean, 100.0 * outliers, tol.mean, 100.0 * tol.outliers, f.p95);
    Ok(())
}
