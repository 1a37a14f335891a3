//! Fuzzing the runtime's readers of outside files other than `.hyb` (which
//! `hybrid_format.rs` fuzzes): OBJ meshes, EXR and PNG images (environment maps, edit
//! masks, `fabric diff`'s inputs). Each valid file is damaged thousands of ways —
//! bytes overwritten, fields set to extremes, truncated, spliced — and read again. A
//! reader may refuse a file with an error; it may not panic, abort on a huge
//! allocation, or hand back something that breaks the invariants the renderers rely on.
//! The damage is `format::mutate`'s (the `.hyb` tests') plus extreme header words.
//! Deterministic (fixed seeds), a few seconds in all.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use fabric_runtime::brdf::twin::SplitMix64;
use fabric_runtime::hybrid::format::mutate::damage;
use fabric_runtime::image::Image;
use fabric_runtime::scene::mesh::{MAX_COORDINATE, Mesh};
use glam::{Vec3, Vec4};

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("reader_fuzz").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Reads `path` with `read` under catch_unwind; a panic fails the test with the case.
fn no_panic<T>(what: &str, case: usize, path: &Path, read: impl FnOnce(&Path) -> T) -> T {
    match catch_unwind(AssertUnwindSafe(|| read(path))) {
        Ok(v) => v,
        Err(_) => {
            let keep = path.with_extension(format!("panic{case}.{}", path.extension().unwrap().to_string_lossy()));
            let _ = std::fs::copy(path, &keep);
            panic!("{what}: case {case} panicked; the file is kept at {}", keep.display());
        }
    }
}

fn check_mesh(m: &Mesh, case: usize) {
    assert!(!m.indices.is_empty() && m.indices.len() % 3 == 0, "case {case}");
    assert!(m.indices.iter().all(|&i| (i as usize) < m.vertices.len()), "case {case}: index out of range");
    assert!(m.triangle_areas().any(|a| a > 0.0), "case {case}: no triangle with area");
    for v in &m.vertices {
        assert!(v.position.iter().all(|c| c.is_finite() && c.abs() <= MAX_COORDINATE), "case {case}: {v:?}");
        assert!(v.uv.iter().all(|c| c.is_finite()), "case {case}: {v:?}");
        let (n, t) = (Vec3::from(v.normal), Vec4::from(v.tangent));
        assert!((n.length() - 1.0).abs() < 1e-3 && (t.truncate().length() - 1.0).abs() < 1e-3 && t.w.abs() == 1.0, "case {case}: frame {v:?}");
    }
}

#[test]
fn damaged_obj_files_are_refused_or_read_sound() {
    let d = tmp("obj");
    let good = "# a quad and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 0.7071 0.7071\n\
                o quad\nf 1/1/1 2/2/1 3/3/1 4/4/1\no roof\nf 3/3/2 4/4/2 5/1/2\n";
    let path = d.join("m.obj");
    std::fs::write(&path, good).unwrap();
    check_mesh(&Mesh::load_obj(&path).unwrap(), 0);
    // Text-level damage as well as bytes: tokens replaced by what breaks parsers.
    let tokens = ["nan", "inf", "-inf", "1e30", "-1", "0", "99999999999", "", "1/", "//", "f", "v", "3.4e38", "1e-45"];
    let mut r = SplitMix64(0x9E37_79B9_7F4A_7C15);
    let (mut ok, mut refused) = (0, 0);
    for case in 1..=3000 {
        let bytes = if case % 2 == 0 {
            damage(good.as_bytes(), good.len(), &mut r)
        } else {
            let mut words: Vec<String> = good.split(' ').map(String::from).collect();
            for _ in 0..1 + r.next_u64() % 3 {
                let i = (r.next_u64() % words.len() as u64) as usize;
                let t = tokens[(r.next_u64() % tokens.len() as u64) as usize];
                // Keep the line break a word may end with, so that lines stay lines.
                words[i] = if words[i].contains('\n') { format!("{t}\n{}", words[i].split_once('\n').unwrap().1) } else { t.to_string() };
            }
            words.join(" ").into_bytes()
        };
        std::fs::write(&path, &bytes).unwrap();
        match no_panic("OBJ", case, &path, |p| Mesh::load_obj(p)) {
            Ok(m) => {
                check_mesh(&m, case);
                ok += 1;
            }
            Err(e) => {
                assert!(e.to_string().contains("m.obj"), "case {case}: the error names the file: {e}");
                refused += 1;
            }
        }
    }
    // Both outcomes occur: the damage is neither always fatal nor always harmless.
    assert!(ok > 100 && refused > 100, "{ok} read, {refused} refused");
}

fn check_image(img: &Image, case: usize) {
    assert!(img.width > 0 && img.height > 0 && img.pixels.len() == img.width as usize * img.height as usize, "case {case}");
}

#[test]
fn damaged_exr_and_png_images_are_refused_or_read_sound() {
    let d = tmp("image");
    let img = Image::from_fn(23, 11, |x, y| Vec3::new(x as f32 * 0.1, y as f32 * 0.2, 0.5));
    for ext in ["exr", "png"] {
        let path = d.join(format!("i.{ext}"));
        img.write(&path, 1.0).unwrap();
        let good = std::fs::read(&path).unwrap();
        check_image(&Image::read(&path, 1.0).unwrap(), 0);
        let mut r = SplitMix64(0xD1B5_4A32_D192_ED03 ^ ext.len() as u64);
        let (mut ok, mut refused) = (0, 0);
        for case in 1..=1500 {
            std::fs::write(&path, damage(&good, good.len(), &mut r)).unwrap();
            match no_panic(ext, case, &path, |p| Image::read(p, 1.0)) {
                Ok(i) => {
                    check_image(&i, case);
                    ok += 1;
                }
                Err(e) => {
                    assert!(e.to_string().contains(&format!("i.{ext}")), "case {case}: the error names the file: {e}");
                    refused += 1;
                }
            }
        }
        assert!(refused > 100, "{ext}: {ok} read, {refused} refused");
    }
}

/// An uncompressed scanline EXR header (B, G, R as f32) claiming `w` × `h` pixels,
/// followed by `tail` bytes instead of the pixels.
fn exr_header(w: i32, h: i32, tail: usize) -> Vec<u8> {
    fn attr(name: &str, ty: &str, data: &[u8]) -> Vec<u8> {
        [name.as_bytes(), b"\0", ty.as_bytes(), b"\0", &(data.len() as i32).to_le_bytes(), data].concat()
    }
    let mut channels = Vec::new();
    for c in ["B", "G", "R"] {
        channels.extend([c.as_bytes(), b"\0", &2i32.to_le_bytes(), &[0u8; 4], &1i32.to_le_bytes(), &1i32.to_le_bytes()].concat());
    }
    channels.push(0);
    let window: Vec<u8> = [0i32, 0, w - 1, h - 1].iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut b = vec![0x76, 0x2f, 0x31, 0x01];
    b.extend(2i32.to_le_bytes());
    b.extend(attr("channels", "chlist", &channels));
    b.extend(attr("compression", "compression", &[0]));
    b.extend(attr("dataWindow", "box2i", &window));
    b.extend(attr("displayWindow", "box2i", &window));
    b.extend(attr("lineOrder", "lineOrder", &[0]));
    b.extend(attr("pixelAspectRatio", "float", &1f32.to_le_bytes()));
    b.extend(attr("screenWindowCenter", "v2f", &[0u8; 8]));
    b.extend(attr("screenWindowWidth", "float", &1f32.to_le_bytes()));
    b.push(0);
    b.extend(vec![0u8; tail]);
    b
}

#[test]
fn an_exr_header_claiming_billions_of_pixels_is_refused_before_they_are_allocated() {
    let path = tmp("exr_huge").join("huge.exr");
    // 30000² pixels would be 10.8 GB of RGB; 100000² more than any machine holds. Both
    // must be refused from the header alone (an allocation abort would kill this test).
    for side in [30000, 100000] {
        std::fs::write(&path, exr_header(side, side, 64)).unwrap();
        let e = Image::read(&path, 1.0).unwrap_err().to_string();
        assert!(e.contains("huge.exr") && e.contains(&format!("{side}x{side}")) && e.contains("too large"), "{e}");
    }
}
