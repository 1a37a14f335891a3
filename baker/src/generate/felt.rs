//! Felt: a non-woven layer of long, curly fibers matted at random, with hairs and
//! loops standing above its top surface.
//!
//! Each fiber is a smooth random walk: its heading turns by N(0, curl²·Δs) per step
//! (a Brownian heading, the usual model of fiber curvature in nonwovens), its
//! elevation relaxes towards the layer plane with spread `tilt`, and it is reflected
//! back at the layer's top and bottom. x and y are left unwrapped; the voxelizer wraps
//! them, so the layer tiles seamlessly. The fiber count follows from the packing
//! fraction: n = packing · area · thickness / (π r² · mean length).

use std::f32::consts::{PI, TAU};

use glam::Vec3;

use super::params::FeltParams;
use super::random::{Rng, stream};

/// The layer's extent in mm: x and y tile size, z range of the matted body.
#[derive(Clone, Copy, Debug)]
pub struct FeltLayout {
    pub size: [f32; 2],
    pub z_bottom: f32,
    pub z_top: f32,
    pub fiber_radius: f32,
}

/// One felt fiber, hair or loop as a polyline (mm) and the index of its colour.
pub struct FeltFiber {
    pub points: Vec<Vec3>,
    pub color: usize,
}

/// How many fibers, hairs and loops a layer gets.
pub fn counts(p: &FeltParams, l: &FeltLayout) -> [usize; 3] {
    let area = l.size[0] * l.size[1];
    let volume = area * (l.z_top - l.z_bottom);
    let fibers = (p.packing * volume / (PI * l.fiber_radius * l.fiber_radius * p.fiber_length)).round() as usize;
    [fibers.max(1), (p.hair_density * area).round() as usize, (p.loop_density * area).round() as usize]
}

/// Body fiber `i`: a curly random walk inside the layer.
pub fn body_fiber(p: &FeltParams, l: &FeltLayout, seed: u64, i: u64, step: f32) -> FeltFiber {
    let mut rng = Rng::new(seed, stream::FELT, i);
    let (lo, hi) = (l.z_bottom + l.fiber_radius, (l.z_top - l.fiber_radius).max(l.z_bottom + l.fiber_radius));
    let mut pos = Vec3::new(rng.range(0.0, l.size[0]), rng.range(0.0, l.size[1]), rng.range(lo, hi));
    let length = p.fiber_length * rng.range(0.5, 1.5);
    let mut heading = rng.range(0.0, TAU);
    let mut elevation = p.tilt * rng.normal();
    let color = (rng.next_u64() % p.colors.len() as u64) as usize;
    let n = ((length / step).ceil() as usize).max(2);
    let ds = length / n as f32;
    let mut points = Vec::with_capacity(n + 1);
    points.push(pos);
    for _ in 0..n {
        heading += p.curl * ds.sqrt() * rng.normal();
        // Ornstein–Uhlenbeck on the elevation: relaxes to 0 over ~1/curl mm, spread `tilt`.
        let k = (p.curl * ds).min(1.0);
        elevation += -k * elevation + p.tilt * (2.0 * k).sqrt() * rng.normal();
        elevation = elevation.clamp(-1.2, 1.2);
        let d = Vec3::new(heading.cos() * elevation.cos(), heading.sin() * elevation.cos(), elevation.sin());
        pos += d * ds;
        if pos.z > hi {
            pos.z = 2.0 * hi - pos.z;
            elevation = -elevation.abs();
        } else if pos.z < lo {
            pos.z = 2.0 * lo - pos.z;
            elevation = elevation.abs();
        }
        pos.z = pos.z.clamp(lo, hi);
        points.push(pos);
    }
    FeltFiber { points, color }
}

/// Hair `i`: rooted just below the surface, rising at about `hair_elevation`, curling.
pub fn hair(p: &FeltParams, l: &FeltLayout, seed: u64, i: u64, step: f32) -> FeltFiber {
    let mut rng = Rng::new(seed, stream::FELT_HAIR, i);
    let depth = 3.0 * l.fiber_radius * rng.uniform();
    let mut pos = Vec3::new(rng.range(0.0, l.size[0]), rng.range(0.0, l.size[1]), l.z_top - depth);
    let length = p.hair_length * rng.range(0.5, 1.5);
    let mut heading = rng.range(0.0, TAU);
    let mut elevation = (p.hair_elevation + 0.25 * rng.normal()).clamp(0.1, 1.45);
    let color = (rng.next_u64() % p.colors.len() as u64) as usize;
    let n = ((length / step).ceil() as usize).max(2);
    let ds = length / n as f32;
    let mut points = Vec::with_capacity(n + 1);
    points.push(pos);
    for _ in 0..n {
        heading += p.curl * ds.sqrt() * rng.normal();
        // Hairs droop slowly towards the plane as they grow.
        elevation = (elevation + 0.3 * ds.sqrt() * rng.normal() - 0.2 * ds).clamp(0.05, 1.45);
        pos += Vec3::new(heading.cos() * elevation.cos(), heading.sin() * elevation.cos(), elevation.sin()) * ds;
        points.push(pos);
    }
    FeltFiber { points, color }
}

/// Loop `i`: leaves the surface and re-enters it, an arch of height ~`loop_height`
/// over a span of ~`loop_span`.
pub fn fiber_loop(p: &FeltParams, l: &FeltLayout, seed: u64, i: u64, step: f32) -> FeltFiber {
    let mut rng = Rng::new(seed, stream::FELT_LOOP, i);
    let depth = 2.0 * l.fiber_radius;
    let start = Vec3::new(rng.range(0.0, l.size[0]), rng.range(0.0, l.size[1]), l.z_top - depth);
    let heading = rng.range(0.0, TAU);
    let span = p.loop_span * rng.range(0.5, 1.5);
    let height = p.loop_height * rng.range(0.3, 1.0) + depth;
    let lean = rng.range(-0.5, 0.5); // the arch leans sideways
    let color = (rng.next_u64() % p.colors.len() as u64) as usize;
    let along = Vec3::new(heading.cos(), heading.sin(), 0.0);
    let side = Vec3::new(-heading.sin(), heading.cos(), 0.0);
    let n = (((span + 2.0 * height) / step).ceil() as usize).max(4);
    let points = (0..=n)
        .map(|k| {
            let a = k as f32 / n as f32;
            let up = (PI * a).sin();
            start + along * (span * a) + (Vec3::Z + side * lean) * (height * up)
        })
        .collect();
    FeltFiber { points, color }
}
