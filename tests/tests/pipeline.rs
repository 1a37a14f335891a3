//! The stages so far, chained on a small generated fabric: generator → geometry →
//! hybrid height field → reference measurement. Checks that the stages agree on
//! units and conventions where they hand data to each other (heights in voxels vs
//! world z vs depth below the tile's top plane; the flyaway mask's voxel order).

use fabric_baker::generate::{Preset, generate};
use fabric_baker::geometry::{GeometryOptions, extract_geometry};
use fabric_baker::reference::measure::MeasureScene;
use fabric_baker::reference::medium::Lookup;
use fabric_runtime::hybrid::{HeightField, Tile};
use fabric_runtime::scene::direction_from_angles;

#[test]
fn generated_fabric_to_geometry_to_measurement() {
    let volume = generate(&Preset::Twill.params(), [96, 96, 32], 5).expect("generate a small twill");
    let [nx, ny, nz] = volume.dims();
    let geometry = extract_geometry(&volume, &GeometryOptions::default()).expect("geometry of a generated twill");
    assert_eq!(geometry.dims, [nx, ny]);
    assert!(geometry.h.iter().all(|h| h.is_finite() && *h >= 0.0 && *h <= nz as f32));
    assert!(geometry.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4 && n.z > 0.0));
    assert!(!geometry.flyaways.voxels.is_empty(), "a twill preset has flyaways");

    // Geometry heights (voxels above the bottom face) → world z for the reference.
    let bbox = volume.bbox();
    let vz = volume.voxel_size().z;
    let world_z: Vec<f32> = geometry.h.iter().map(|h| bbox.min.z + h * vz).collect();

    // The same heights through the hybrid model's height field (depth below the top
    // plane, 16-bit) must land on the same world z, within its quantization.
    let tile = Tile::from_source(bbox, [nx as u32, ny as u32, nz as u32]);
    let field = HeightField::from_voxel_heights(nx as u32, ny as u32, &geometry.h, nz as u32, &tile).expect("height field from geometry");
    let step = tile.height_scale / 65535.0;
    for j in 0..ny {
        for i in 0..nx {
            let z_hybrid = tile.top_z - field.depth_fraction(i as u32, j as u32) * tile.height_scale;
            let z_geometry = world_z[i + nx * j];
            assert!((z_hybrid - z_geometry).abs() <= step + 1e-6 * tile.height_scale, "texel ({i}, {j}): {z_hybrid} vs {z_geometry}");
        }
    }

    // Measure the surface without its flyaways (paper §5.3: "the complement of V").
    let mask = geometry.flyaway_mask().to_bools();
    assert_eq!(mask.len(), nx * ny * nz);
    let removed = mask.iter().filter(|m| **m).count();
    assert_eq!(removed, geometry.flyaways.voxels.len(), "the mask removes exactly the flyaway voxels");
    let scene = MeasureScene::new(&volume, Lookup::Trilinear, Some(&world_z), Some(&mask)).expect("measurement scene");
    let (wi, wo) = (direction_from_angles(30.0, 0.0), direction_from_angles(30.0, 180.0));
    let (img, stats) = scene.render_image(wi, wo, 4, 1).expect("a measurement image");
    assert_eq!((img.width as usize, img.height as usize), (nx, ny));
    assert!(img.first_non_finite().is_none() && img.pixels.iter().all(|p| p.min_element() >= 0.0));
    assert!(img.mean() > 1e-3, "a lit woven surface reflects: mean {}", img.mean());
    assert_eq!(stats.truncated, 0);
    // Bit-identical on a second run with the same seed.
    assert_eq!(scene.render_image(wi, wo, 4, 1).unwrap().0, img);
}
