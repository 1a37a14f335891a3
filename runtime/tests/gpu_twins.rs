//! The functions of the hybrid renderer's GLSL includes against their Rust twins, one by
//! one, through `shaders/twin_eval.comp` on the local Vulkan device (lavapipe in CI), as
//! `brdf_glsl.rs` does for the BRDF: packing (f16, snorm16, unorm16, octahedral and
//! tangent-angle decoding), the height-field march and shadow rays, the flyaway march,
//! a texel's response, the level choice, texel lookups, the scalars and a coarse
//! flyaway's spread axes. Random and
//! extreme inputs (grazing rays, rays along texel lines, tiny step budgets) on a clamped
//! and a periodic model.

#![cfg(feature = "gpu")]

use bytemuck::{Pod, Zeroable};
use fabric_runtime::brdf::twin::SplitMix64;
use fabric_runtime::brdf::{DiffuseLaw, cloth_diffuse_cosine, cloth_diffuse_env_factor, cloth_visibility, cloth_visibility_gradient};
use fabric_runtime::cpu::flyaways::{FlyawayGrid, flyaway_opacity, visit_flyaways};
use fabric_runtime::cpu::heightfield::{HeightTracer, HfTrace};
use fabric_runtime::cpu::shading::{texel_response, volume_factor};
use fabric_runtime::cpu::{CpuRenderOptions, LevelChoice, Scene};
use fabric_runtime::hybrid::gpu_layout::{GpuModel, GpuRenderParams, LEVEL_AUTO};
use fabric_runtime::hybrid::packing::{f16_bits, f16_value, octahedral_decode, octahedral_encode, snorm16_value, tangent_angle_decode, unorm16_value};
use fabric_runtime::hybrid::{HybridModel, PackedAxisSpread, examples};
use fabric_runtime::scene::Ray;
use fabric_runtime::vk::{Buffer, CheckedDevice};

mod support;
use glam::{Vec2, Vec3, Vec4};

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct TwinInput {
    kind: u32,
    level: u32,
    i: u32,
    j: u32,
    u: [u32; 4],
    a: [f32; 4],
    b: [f32; 4],
    c: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct TwinOutput {
    x: [f32; 4],
    y: [f32; 4],
    z: [f32; 4],
    w: [f32; 4],
}

fn evaluate(device: &CheckedDevice, model: &HybridModel, periodic: bool, inputs: &[TwinInput]) -> Vec<TwinOutput> {
    let layout_data = GpuModel::new(model, periodic).unwrap();
    let mut buffers: Vec<Buffer> = layout_data.arrays().iter().map(|(name, bytes)| support::storage(device, name, bytes)).collect();
    // No lights (the flyaway march's radiance is zero), automatic levels with a bias.
    let mut params: GpuRenderParams = Zeroable::zeroed();
    params.level_mode = LEVEL_AUTO;
    params.level_bias = 0.3;
    params.max_steps = 4096;
    params.edit_tint = [1.0; 4];
    params.edit_roughness = 1.0;
    buffers.push(support::storage(device, "params", bytemuck::bytes_of(&params)));
    buffers.push(support::storage(device, "mask", &[0u8; 4]));
    buffers.push(support::storage(device, "inputs", bytemuck::cast_slice(inputs)));
    buffers.push(support::storage(device, "unused 10", &[0u8; 16]));
    buffers.push(support::storage(device, "unused 11", &[0u8; 16]));
    for (name, bytes) in [layout_data.transmission_array(), layout_data.view_tilt_array()] {
        buffers.push(support::storage(device, &name, &bytes));
    }
    let refs: Vec<&Buffer> = buffers.iter().collect();
    let out = support::run_compute(device, "twin_eval.comp", &refs, (inputs.len() * size_of::<TwinOutput>()) as u64, inputs.len() as u32);
    bytemuck::pod_collect_to_vec(&out)
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    v.extend(w).to_array()
}

/// A downward ray from above the tile: random, grazing, or along a texel line.
fn random_ray(rng: &mut SplitMix64, m: &HybridModel) -> (Vec3, Vec3) {
    let t = &m.tile;
    let texel = m.texel_size();
    let mut o = Vec3::new(t.origin.x + rng.range(-0.1, 1.1) * t.size.x, t.origin.y + rng.range(-0.1, 1.1) * t.size.y, t.top_z + rng.range(0.0, 0.5) * t.height_scale);
    let mut d = rng.unit_vector();
    d.z = -d.z.abs();
    match rng.next_u64() % 4 {
        0 => d = Vec3::new(d.x, d.y, -0.02 * rng.next_f32() - 1e-4).normalize(), // grazing
        1 => o.x = t.origin.x + (rng.next_u64() % 40) as f32 * texel.x, // on a texel line
        2 => d = Vec3::new(0.0, d.y, d.z).normalize(), // along an axis
        _ => {}
    }
    (o, d)
}

fn check(model: &HybridModel, periodic: bool, device: &CheckedDevice) {
    let mut rng = SplitMix64(if periodic { 11 } else { 12 });
    let tracer = HeightTracer::new(model, periodic);
    let options = CpuRenderOptions { periodic, level: LevelChoice::Auto { bias: 0.3 }, ..Default::default() };
    let scene = Scene::for_rays(model, &[], options).unwrap();
    let reading = model.meta.reading;
    let mut inputs = Vec::new();
    let per_kind = 4000;
    for kind in 0..9u32 {
        for k in 0..per_kind {
            let mut e = TwinInput { kind, ..Default::default() };
            match kind {
                0 => {
                    let f = if k % 7 == 0 { [0.0, -0.0, 65504.0, 6.0e-8][k % 4] } else { rng.log_range(1e-6, 6e4) };
                    e.u = [rng.next_u64() as u32, (rng.next_u64() & 0xffff) as u32, f16_bits(f) as u32, (rng.next_u64() & 0xffff) as u32];
                }
                1 | 2 => {
                    let (o, d) = random_ray(&mut rng, model);
                    let steps = if k % 10 == 0 { 1 + (rng.next_u64() % 16) as u32 } else { 4096 };
                    e.u[0] = steps;
                    // A quadtree floor on some rays (coarse relief).
                    e.u[1] = if k % 3 == 1 { (rng.next_u64() % 5) as u32 } else { 0 };
                    if kind == 1 {
                        // From the top plane (as the renderer starts) or from the origin.
                        let t0 = if k % 4 == 0 { 0.0 } else { ((model.tile.top_z - o.z) / d.z).max(0.0) };
                        e.a = v4(o, t0);
                        e.b = v4(d, if k % 5 != 0 { f32::MAX } else { t0 + rng.range(0.0, 3.0) * model.tile.height_scale });
                        e.c = [if k % 5 == 0 { 1e-4 } else { 0.0 }, o.x, o.y, 0.0];
                    } else {
                        let (x, y) = (o.x, o.y);
                        let p = Vec3::new(x, y, model.tile.top_z - tracer.depth_at(x, y));
                        let mut wi = rng.unit_vector();
                        wi.z = if k % 9 == 0 { 0.01 * rng.next_f32() } else { wi.z.abs() };
                        e.a = v4(p, 0.0);
                        e.b = v4(wi.normalize(), if k % 2 == 0 { f32::INFINITY } else { rng.range(0.0, 2.0) });
                    }
                }
                3 => {
                    let levels: Vec<usize> = (0..model.levels.len()).filter(|&l| model.levels[l].flyaways.as_ref().is_some_and(|f| !f.nodes.is_empty())).collect();
                    let (mut o, d) = random_ray(&mut rng, model);
                    e.level = levels[k % levels.len()] as u32;
                    // Mostly above a column that has voxels, so that marches cross them.
                    let f = model.levels[e.level as usize].flyaways.as_ref().unwrap();
                    let filled: Vec<usize> = (0..f.heads.len()).filter(|&c| f.heads[c] != fabric_runtime::hybrid::NO_NODE).collect();
                    if k % 4 != 0 {
                        let c = filled[(rng.next_u64() % filled.len() as u64) as usize];
                        let w = model.levels[e.level as usize].width as usize;
                        let span = model.texel_size() * (1u32 << e.level) as f32;
                        let xy = model.tile.origin + span * Vec2::new((c % w) as f32 + rng.next_f32(), (c / w) as f32 + rng.next_f32());
                        // Back along the ray to above the top plane.
                        let back = (o.z - model.tile.top_z) / -d.z;
                        o = (xy.extend(model.tile.top_z) - d * (back + 0.3 * model.tile.height_scale / -d.z)).with_z(o.z.max(model.tile.top_z));
                    }
                    e.u[0] = if k % 10 == 0 { 3 } else { 16384 };
                    let t0 = (model.tile.top_z - o.z) / d.z;
                    e.a = v4(o, t0.max(0.0));
                    e.b = v4(d, t0.max(0.0) + model.tile.height_scale / -d.z);
                }
                4 => {
                    let level = (rng.next_u64() % model.levels.len() as u64) as usize;
                    let l = &model.levels[level];
                    (e.level, e.i, e.j) = (level as u32, (rng.next_u64() % l.width as u64) as u32, (rng.next_u64() % l.height as u64) as u32);
                    e.a = v4(rng.unit_vector(), 0.0);
                    e.b = v4(rng.unit_vector(), 0.0);
                }
                5 => {
                    let s = rng.log_range(1e-3, 1e3) * model.texel_size().x;
                    let a = Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * s;
                    let b = if k % 3 == 0 { a.perp() * rng.range(0.0, 1.0) } else { Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * s };
                    e.u[0] = (k % 17 != 0) as u32;
                    e.a = [a.x, a.y, b.x, b.y];
                }
                6 => {
                    let (o, _) = random_ray(&mut rng, model);
                    e.level = (rng.next_u64() % model.levels.len() as u64) as u32;
                    e.u[0] = (k % 4) as u32;
                    e.a = v4(o, 0.0);
                }
                8 => {
                    // Any tangent code and record, weights summing past 1 included (clamped),
                    // zero spreads (one axis) and axes on the z = 0 seam of the basis.
                    let t = if k % 11 == 0 { octahedral_encode(Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0)) } else { [rng.next_u64() as u16, rng.next_u64() as u16] };
                    let record = if k % 13 == 0 { rng.next_u64() as u32 & 0xffff } else { rng.next_u64() as u32 };
                    // Any second group (format 1.8), none (share 0) one time in three.
                    let group = if k % 3 == 0 { rng.next_u64() as u32 & 0xff00_ffff } else { rng.next_u64() as u32 };
                    e.u = [t[0] as u32 | (t[1] as u32) << 16, record, (k % 4) as u32, group];
                }
                _ => {
                    e.a = v4(rng.unit_vector(), 0.0);
                    e.b = v4(rng.unit_vector(), 0.0);
                    e.c = [rng.range(0.0, 1.0), rng.range(-0.1, 2.0), rng.log_range(1e-3, 1.0), 0.0];
                    // A visibility gradient, past its clamp one time in five (its own
                    // stream, so that the other scalars' inputs stay as they were).
                    let s = if k % 5 == 0 { 3.0 } else { 1.0 };
                    let mut own = SplitMix64(0x6772_0000 + k as u64);
                    e.u = [0; 4].map(|_| own.range(-s, s).to_bits());
                }
            }
            inputs.push(e);
        }
    }
    let out = evaluate(device, model, periodic, &inputs);
    let mut mismatches = [0usize; 9];
    let mut worst = [0f32; 9];
    // How many march inputs end in a hit, a step limit, a crossed flyaway: the test must
    // exercise each outcome, not agree on misses.
    let (mut hits, mut limits, mut crossed) = (0, 0, 0);
    // Level choices that read a box grid (lookups across both axes).
    let mut box_grids = 0;
    // ... and flyaway grids longer along the footprint's major axis.
    let mut anisotropic_fly_grids = 0;
    let mut shadows_blended = 0;
    let rel = |a: f32, b: f32, floor: f32| (a - b).abs() / a.abs().max(b.abs()).max(floor);
    for (e, g) in inputs.iter().zip(&out) {
        let k = e.kind as usize;
        let (gx, gy, gz) = (Vec4::from(g.x), Vec4::from(g.y), Vec4::from(g.z));
        let err = match e.kind {
            0 => {
                let n = octahedral_decode([e.u[0] as u16, (e.u[0] >> 16) as u16]);
                let t = tangent_angle_decode(n, e.u[1] as u16);
                let f = f16_value(e.u[2] as u16);
                let s = snorm16_value(e.u[3] as u16);
                let u = unorm16_value(e.u[3] as u16);
                let bad_exact = f != gx.w || s != gy.w || u != gz.x;
                if bad_exact { 1.0 } else { (gx.truncate() - n).abs().max_element().max((gy.truncate() - t).abs().max_element()) }
            }
            1 => {
                let (o, d) = (Vec4::from(e.a).truncate(), Vec4::from(e.b).truncate());
                let mut steps = 0;
                let h = tracer.trace_to(&Ray::new(o, d), e.a[3], e.b[3], e.c[0], e.u[0], &mut steps, e.u[1] as usize);
                let (kind, t) = match h {
                    HfTrace::Miss => (0.0, 0.0),
                    HfTrace::Hit(t) => (1.0, t),
                    HfTrace::StepLimit => (2.0, 0.0),
                };
                let depth = tracer.depth_at(e.c[1], e.c[2]);
                hits += (kind == 1.0) as usize;
                limits += (kind == 2.0) as usize;
                if kind != gx.x { 1.0 } else { rel(t, gx.y, 1e-3 * model.texel_size().x).max(rel(depth, gx.w, 1e-6)) }
            }
            2 => {
                let (blocked, limited) = tracer.occluded(Vec4::from(e.a).truncate(), Vec4::from(e.b).truncate(), e.b[3], e.u[0]);
                if (blocked as u32 as f32, limited as u32 as f32) == (gx.x, gx.y) { 0.0 } else { 1.0 }
            }
            3 => {
                let level = e.level as usize;
                let f = model.levels[level].flyaways.as_ref().unwrap();
                let grid = FlyawayGrid::new(model, level, periodic);
                let (o, d) = (Vec4::from(e.a).truncate(), Vec4::from(e.b).truncate());
                let m = visit_flyaways(f, &grid, &Ray::new(o, d), e.a[3], e.b[3], e.u[0], |_, _, _, _| {});
                crossed += (m.transmittance < 1.0) as usize;
                if m.columns as f32 != gy.x || m.limited as u32 as f32 != gy.y { 1.0 } else { (m.transmittance - gx.w).abs() }
            }
            4 => {
                let b = model.levels[e.level as usize].texel_brdf(e.i, e.j);
                let r = texel_response(&b, Vec4::from(e.a).truncate(), Vec4::from(e.b).truncate(), reading, model.meta.diffuse);
                let scale = r.max_element().max(1e-6);
                (r - gx.truncate()).abs().max_element() / scale
            }
            5 => {
                let axes = (e.u[0] != 0).then(|| (Vec2::new(e.a[0], e.a[1]), Vec2::new(e.a[2], e.a[3])));
                let m = scene.level_mix_axes(axes);
                // x.w holds taps + 1000 · fly_taps.0 + 100000 · fly_taps.1; y.z, y.w the fly
                // levels + 64 · the shadow levels; z.y taps_minor + the shadow weight / 2.
                let same = (m.lo as f32, m.hi as f32, (m.taps + 1000 * m.fly_taps.0 + 100_000 * m.fly_taps.1) as f32, (m.fly.0 + 64 * m.shadow.0) as f32, (m.fly.1 + 64 * m.shadow.1) as f32, m.taps_minor as f32) == (gx.x, gx.y, gx.w, gy.z, gy.w, gz.y.floor());
                let shadow_weight = (m.shadow.2 - 2.0 * gz.y.fract()).abs();
                shadows_blended += (m.shadow.2 > 0.0) as usize;
                box_grids += (m.taps_minor > 1 && m.fly_taps.1 > 1) as usize;
                anisotropic_fly_grids += (m.fly_taps.0 > m.fly_taps.1) as usize;
                let gw = Vec4::from(g.w);
                let scale = m.fly_axes.0.length().max(m.fly_axes.1.length()).max(1e-30);
                let fly_axes = (m.fly_axes.0 - Vec2::new(gw.x, gw.y)).abs().max_element().max((m.fly_axes.1 - Vec2::new(gw.z, gw.w)).abs().max_element()) / scale;
                let axis = ((m.axis - Vec2::new(gy.x, gy.y)).abs().max_element()) / m.axis.length().max(1e-30);
                let minor = ((m.minor_axis - Vec2::new(gz.z, gz.w)).abs().max_element()) / m.minor_axis.length().max(m.axis.length()).max(1e-30);
                if !same { 1.0 } else { (m.weight - gx.z).abs().max((m.fly.2 - gz.x).abs()).max(shadow_weight).max(axis).max(minor).max(fly_axes) }
            }
            6 => {
                let p = Vec4::from(e.a).truncate();
                let level = e.level as usize;
                let corners = scene.bilinear_texels(p, level);
                let (cb, cw) = corners[e.u[0] as usize];
                let gpu_texel = model.levels[level].texel_brdf(gx.x as u32, gx.y as u32);
                let (ti, tj) = scene.texel_at(p, level);
                if cb != gpu_texel || (ti as f32, tj as f32) != (gy.x, gy.y) { 1.0 } else { (cw - gx.z).abs() }
            }
            8 => {
                let node = fabric_runtime::hybrid::FlyawayNode { tangent: [e.u[0] as u16, (e.u[0] >> 16) as u16], ..Default::default() };
                let record: PackedAxisSpread = bytemuck::cast([e.u[1], 0u32]);
                let group: fabric_runtime::hybrid::PackedAxisGroup = bytemuck::cast(e.u[3]);
                let s = group.axes(record.axes(&node));
                let first = 2 * e.u[2].min(3) as usize;
                let half = if first >= 4 { 4 } else { 0 };
                let axes = (s.axes[first] - gx.truncate()).abs().max_element().max((s.axes[first + 1] - gy.truncate()).abs().max_element());
                axes.max((Vec4::from_slice(&s.weights[half..half + 4]) - gz).abs().max_element())
            }
            _ => {
                let vf = volume_factor(Vec4::from(e.a).truncate(), Vec4::from(e.b).truncate());
                let op = flyaway_opacity(e.c[0], e.c[1], e.c[2]);
                // The Lommel–Seeliger diffuse factors about a normal tilted by the inputs.
                let (wi, wo) = (Vec4::from(e.a).truncate(), Vec4::from(e.b).truncate());
                let n = Vec3::new(e.a[1], e.b[0], 1.0).normalize();
                let d = cloth_diffuse_cosine(DiffuseLaw::LommelSeeliger, n, wi, wo);
                let h = cloth_diffuse_env_factor(DiffuseLaw::LommelSeeliger, wo);
                let g = e.u.map(f32::from_bits);
                let m = cloth_visibility_gradient(g, wi, wo);
                // With a curvature made from the same inputs (format 1.15; twin_eval.comp).
                let v = cloth_visibility(g, [g[0], g[1], g[2] * g[3], g[2], g[3], g[0] * g[1]], wi, wo);
                rel(vf, gx.x, 1e-6).max((op - gx.y).abs()).max(rel(d, gx.z, 1e-6)).max(rel(h, gx.w, 1e-6)).max((m - gy.x).abs()).max((v - gy.y).abs())
            }
        };
        // A NaN anywhere in the GPU's outputs is a mismatch: the max chains above drop NaN
        // operands, and the CPU twin writes none.
        let gpu_nan = [g.x, g.y, g.z, g.w].iter().flatten().any(|v| v.is_nan());
        let err = if gpu_nan { f32::INFINITY } else { err };
        // Per kind: an error above 1e-4 (or NaN) counts as a mismatch (a different branch
        // taken, or more than a few ulps).
        let agrees = err <= 1e-4;
        if !agrees {
            mismatches[k] += 1;
        }
        worst[k] = worst[k].max(if agrees { err } else { 0.0 });
    }
    println!("marches: {hits} hits and {limits} step limits of {per_kind} rays, {crossed} of {per_kind} flyaway marches cross a voxel");
    assert!(hits > per_kind / 4 && limits > 0 && crossed > per_kind / 4, "inputs too easy: {hits} hits, {limits} limits, {crossed} crossings");
    assert!(box_grids > per_kind / 10, "only {box_grids} of {per_kind} level choices read a box grid");
    assert!(shadows_blended > per_kind / 20, "only {shadows_blended} of {per_kind} level choices blend two shadow levels");
    assert!(anisotropic_fly_grids > per_kind / 20, "only {anisotropic_fly_grids} of {per_kind} level choices march an anisotropic flyaway grid");
    let names = ["packing", "height-field march", "shadow rays", "flyaway march", "texel response", "level choice", "texel lookups", "scalars", "spread axes"];
    for k in 0..9 {
        println!("{} tile, {}: {} of {per_kind} differ, worst agreeing error {:.1e}", if periodic { "periodic" } else { "clamped" }, names[k], mismatches[k], worst[k]);
    }
    // Exact kinds (integer decisions, table lookups, decodings of the same bits) may not
    // differ at all; the marches may take another branch where an ulp of the GPU's
    // arithmetic moves a crossing onto the other side of a leaf or column edge: measured
    // on lavapipe, see the printed counts; 0.5% allowed.
    for k in [0, 4, 5, 6, 7, 8] {
        assert_eq!(mismatches[k], 0, "{}: {} mismatches", names[k], mismatches[k]);
    }
    for k in [1, 2, 3] {
        assert!(mismatches[k] * 200 <= per_kind, "{}: {} of {per_kind} differ", names[k], mismatches[k]);
    }
}

#[test]
fn every_include_agrees_with_its_rust_twin() {
    let device = CheckedDevice::new().expect("a Vulkan device (lavapipe in CI)");
    check(&examples::sample_model(), false, &device);
    // The width reading, read by the shader from the model's flags.
    let mut width = examples::synthetic_model(64, 7);
    width.meta.reading = fabric_runtime::brdf::BrdfReading::Width;
    check(&width, true, &device);
    // The Lommel–Seeliger diffuse law (format 1.6) through texel_response, under the held
    // reading (format 1.14).
    let mut ls = examples::synthetic_model(64, 7);
    ls.meta.diffuse = DiffuseLaw::LommelSeeliger;
    ls.meta.reading = fabric_runtime::brdf::BrdfReading::Held;
    // With a visibility gradient on every level (format 1.12: read after the view tilts
    // in binding 13) and a curvature (format 1.15: after the gradients) through
    // texel_response.
    examples::add_view_tilts(&mut ls, 0.3, 5);
    examples::add_gradients(&mut ls, 7);
    examples::add_curvatures(&mut ls, 3);
    check(&ls, true, &device);
}
