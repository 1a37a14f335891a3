//! A coarse flyaway node's response against the mean of the level-0 nodes it merges, at
//! one view and the far views' light: per level, the sum over nodes of the coarse
//! response over the sum of its cell's α-weighted mean level-0 response, the quartiles
//! of the per-node ratio, and how much of the coarse voxels lies above the surface
//! (baker/PREFILTER_MEASUREMENTS.md, "Coarse flyaways").
//!
//! `cargo run --release -p fabric-baker --example flyaway_cells MODEL.hyb [POLAR]`;
//! with `DUMP=1` also the first level-1 nodes of two or more children, their axes and
//! their children's.

use fabric_baker::prefilter::far_view::{VIEW_AZIMUTH, far_light};
use fabric_runtime::brdf::cloth_frame;
use fabric_runtime::cpu::shading::{in_fiber_frame, texel_response};
use fabric_runtime::hybrid::{Flyaways, HybridModel, format};
use glam::Vec3;

fn node_response(model: &HybridModel, f: &Flyaways, index: usize, wi: Vec3, wo: Vec3) -> f64 {
    let node = &f.nodes[index];
    let base = f.table.brdf_in_frame(node.param as usize, cloth_frame(Vec3::Z, Vec3::X));
    let axes = f.node_axes(index);
    (0..8).map(|k| axes.weights[k] as f64 * { let r = texel_response(&in_fiber_frame(base, axes.axes[k], wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, fabric_runtime::brdf::DiffuseLaw::Lambert); (r.x + r.y + r.z) as f64 / 3.0 }).sum()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = format::read_file(std::path::Path::new(&args[1])).expect("read the model");
    let polar: f32 = args.get(2).map_or(0.0, |s| s.parse().unwrap());
    let wo = fabric_runtime::scene::direction_from_angles(polar, VIEW_AZIMUTH);
    let wi = far_light().sample(Vec3::ZERO).wi;
    let f0 = model.levels[0].flyaways.as_ref().unwrap();
    let w0 = model.width();
    for level in 1..model.levels.len().min(6) {
        let Some(f) = &model.levels[level].flyaways else { continue };
        let lw = model.levels[level].width;
        let (mut fine, mut coarse, mut fine_alpha, mut coarse_alpha) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let (mut fine_w, mut coarse_w) = (0.0f64, 0.0f64);
        let mut per_cell = std::collections::BTreeMap::new();
        for j in 0..model.height_px() {
            for i in 0..w0 {
                for (index, node) in f0.list((j * w0 + i) as usize).with_index() {
                    let e = per_cell.entry((i >> level, j >> level, node.depth as u32 >> level)).or_insert((0.0f64, 0.0f64));
                    e.0 += node.alpha() as f64 * node_response(&model, f0, index, wi, wo);
                    e.1 += node.alpha() as f64;
                }
            }
        }
        let mut ratios = Vec::new();
        let mut children: std::collections::BTreeMap<(u32, u32, u32), Vec<(Vec3, f64)>> = std::collections::BTreeMap::new();
        if std::env::var("DUMP").is_ok() && level == 1 {
            for j in 0..model.height_px() {
                for i in 0..w0 {
                    for (index, node) in f0.list((j * w0 + i) as usize).with_index() {
                        children.entry((i >> level, j >> level, node.depth as u32 >> level)).or_default().push((node.tangent(), node_response(&model, f0, index, wi, wo)));
                    }
                }
            }
        }
        let mut dumped = 0;
        for j in 0..model.levels[level].height {
            for i in 0..lw {
                for (index, node) in f.list((j * lw + i) as usize).with_index() {
                    let (sf, sa) = per_cell.get(&(i, j, node.depth as u32)).copied().unwrap_or_default();
                    let c = node_response(&model, f, index, wi, wo);
                    if let Some(ch) = children.get(&(i, j, node.depth as u32)).filter(|ch| ch.len() >= 2 && dumped < 12) {
                        dumped += 1;
                        let a = f.node_axes(index);
                        println!("   record {:?}", f.spreads.as_ref().map(|s| s[index]));
                        println!("node {index} at ({i}, {j}, {}) alpha {:.3}: coarse {c:.4} tangent {:.2} axes", node.depth, node.alpha(), node.tangent());
                        println!("    {:?} w {:?}", a.axes.map(|v| format!("{:.2} {:.2} {:.2}", v.x, v.y, v.z)), a.weights);
                        for (t, r) in ch {
                            println!("    child {:.2} {:.2} {:.2} response {r:.4}", t.x, t.y, t.z);
                        }
                    }
                    fine += sf / sa.max(1e-9);
                    coarse += c;
                    fine_w += node.alpha() as f64 * sf / sa.max(1e-9);
                    coarse_w += node.alpha() as f64 * c;
                    fine_alpha += sa;
                    coarse_alpha += node.alpha() as f64;
                    if sf > 0.0 {
                        ratios.push(c / (sf / sa));
                    }
                }
            }
        }
        // How much of each coarse node lies above the surface (depth below the top plane
        // of the surface at each level-0 column of its footprint).
        let s_l = model.voxel_depth(level);
        let (mut free, mut count, mut straddle) = (0.0f64, 0usize, 0usize);
        for j in 0..model.levels[level].height {
            for i in 0..lw {
                for node in f.list((j * lw + i) as usize) {
                    let top = node.depth as f32 * s_l;
                    let (mut fr, mut n) = (0.0f32, 0);
                    for jj in (j << level)..((j + 1) << level).min(model.height_px()) {
                        for ii in (i << level)..((i + 1) << level).min(w0) {
                            fr += ((model.depth(ii, jj) - top) / s_l).clamp(0.0, 1.0);
                            n += 1;
                        }
                    }
                    let fr = fr / n as f32;
                    free += fr as f64;
                    count += 1;
                    straddle += (fr < 0.99) as usize;
                }
            }
        }
        println!("  level {level}: mean free fraction {:.3}, {} of {} nodes reach below the surface", free / count as f64, straddle, count);
        ratios.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let q = |p: f64| ratios.get(((ratios.len() as f64 - 1.0) * p) as usize).copied().unwrap_or(f64::NAN);
        if let Some(g) = &f.groups {
            let split: Vec<f32> = g.iter().filter(|g| g.share > 0).map(|g| g.share()).collect();
            println!("  level {level}: {} of {} nodes in two groups, mean second share {:.2}", split.len(), g.len(), split.iter().sum::<f32>() / split.len().max(1) as f32);
        }
        println!("level {level}: {} nodes; Σ coarse response / Σ cells' mean fine response {:.3}; α-weighted {:.3}; per node ratio quartiles {:.2} {:.2} {:.2}; Σα coarse {:.0} fine {:.0}", f.nodes.len(), coarse / fine, coarse_w / fine_w, q(0.25), q(0.5), q(0.75), coarse_alpha, fine_alpha);
    }
}
