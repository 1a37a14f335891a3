//! Marching the height field (the CPU twin of `heightfield.glsl`): parallax occlusion
//! mapping made exact with a conservative accelerator (DESIGN.md §7).
//!
//! The surface is the bilinear interpolation of the depth samples at texel centres
//! (runtime/HYBRID_FORMAT.md §5.2). Between four neighbouring centres it is one bilinear
//! patch, a **leaf**. Along a ray, depth below the top plane D(t) is linear and the
//! patch's depth h(t) is quadratic, so g(t) = D(t) − h(t) is a quadratic per leaf: the
//! first t with g ≥ 0 is the hit.
//!
//! - **Leaf space** q: q = (x − x0)/Δ − ½ + offset, so leaf (cx, cy) spans
//!   q ∈ [cx, cx+1] × [cy, cy+1] with corners at the centres of texels
//!   (cx − offset .. cx − offset + 1). offset = 1 on a clamped tile (the half texels at
//!   the edges are leaves too: n + 1 leaves, the tile is q ∈ [½, n + ½]); offset = 0 on
//!   a periodic tile (n leaves, the tile is q ∈ [0, n], repeated).
//! - **Accelerator**: a min-depth quadtree over the leaves (a "maximum mipmap" of
//!   heights, Tevs et al. 2008): a node's bound is the least depth of any leaf corner
//!   under it, and a bilinear patch never rises above its highest corner, so a ray
//!   segment whose deepest point is shallower than the bound cannot hit inside the node
//!   and skips it whole. Stackless traversal: descend where a hit is possible, step to
//!   the neighbour cell, ascend one level on leaving a parent.
//! - **Refinement**: in a leaf, g is sampled as its exact quadratic; the first root is
//!   bracketed (ends and the maximum of g) and refined by [`REFINE_STEPS`] bisections.
//!
//! Rays are parameterized by world distance t (unit direction).

use glam::{Vec2, Vec3};

use crate::hybrid::HybridModel;
use crate::scene::Ray;

/// Bisection steps of the refinement: the hit is located to 2⁻²⁰ of the leaf segment.
pub const REFINE_STEPS: u32 = 20;

/// Steps of a march after which it descends one quadtree level less (and one more per as
/// many steps again): a node at or above that floor is a hit on its flat top, as under
/// `trace_to`'s `floor`. A ray near the horizon of a periodic sheet skims the crests of
/// hundreds of tiles, descending into each: at 89.99° over a felt, every ray of a pixel's
/// grids ran to the 4096-step budget and lavapipe drew a 160×90 frame in 15 s. Rays that
/// meet the surface within this many steps are exact and unchanged (the presets' camera
/// rays take at most 148 at 89°). Twin: HF_STEPS_PER_FLOOR in shaders/common/heightfield.glsl.
pub const STEPS_PER_FLOOR: u32 = 512;

/// Repeats of a periodic tile a march crosses below the shallowest depth before it takes
/// the next repeat's flat top (its shallowest depth, which the ray is already below) as the
/// hit. A ray that has skimmed this many tiles' crests without meeting one is within a
/// fraction of a degree of the horizon (at 89.99° over a felt, 300 of them), where its
/// pixel spans thousands of texels. The presets' views to 89.5° are unchanged by it.
/// Twin: HF_SKIM_TILES in shaders/common/heightfield.glsl.
pub const SKIM_TILES: u32 = 16;

/// The outcome of a march.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HfTrace {
    /// The surface at ray parameter t.
    Hit(f32),
    /// No surface along the segment (or the ray left a clamped tile).
    Miss,
    /// The step budget ran out first.
    StepLimit,
}

/// A ray in leaf space: q(t) = q0 + dq·t, depth D(t) = d0 + dd·t (world units below the
/// top plane), t = world distance from where it was set up.
#[derive(Clone, Copy, Debug)]
pub struct HfRay {
    pub q0: Vec2,
    pub dq: Vec2,
    pub d0: f32,
    pub dd: f32,
}

impl HfRay {
    #[inline]
    fn q(&self, t: f32) -> Vec2 {
        self.q0 + self.dq * t
    }

    #[inline]
    fn depth(&self, t: f32) -> f32 {
        self.d0 + self.dd * t
    }
}

/// One level of the min-depth quadtree.
#[derive(Clone, Debug)]
struct MinLevel {
    dims: [i32; 2],
    min_depth: Vec<f32>,
}

/// The height field of a model, ready to be marched (clamped or periodic).
#[derive(Clone, Debug)]
pub struct HeightTracer {
    periodic: bool,
    /// Samples (level-0 texels) per axis.
    n: [i32; 2],
    /// World depths below the top plane at texel centres, x fastest.
    samples: Vec<f32>,
    /// Leaf-space shift: 1 clamped, 0 periodic.
    offset: i32,
    /// Quadtree, level 0 = leaves, last = 1×1.
    levels: Vec<MinLevel>,
    origin: Vec2,
    texel: Vec2,
    /// 1 / `texel` (HybridModel::inv_texel_size): texel coordinates are products.
    inv_texel: Vec2,
    top_z: f32,
    height_scale: f32,
}

impl HeightTracer {
    /// Decodes the height field and builds the quadtree (O(texels)).
    pub fn new(model: &HybridModel, periodic: bool) -> HeightTracer {
        let n = [model.width() as i32, model.height_px() as i32];
        let samples: Vec<f32> = (0..n[1]).flat_map(|j| (0..n[0]).map(move |i| (i, j))).map(|(i, j)| model.depth(i as u32, j as u32)).collect();
        let offset = if periodic { 0 } else { 1 };
        let leaves = [n[0] + offset, n[1] + offset];
        let mut tracer = HeightTracer { periodic, n, samples, offset, levels: Vec::new(), origin: model.tile.origin, texel: model.texel_size(), inv_texel: model.inv_texel_size(), top_z: model.tile.top_z, height_scale: model.tile.height_scale };
        let mut level0 = Vec::with_capacity((leaves[0] * leaves[1]) as usize);
        for cy in 0..leaves[1] {
            for cx in 0..leaves[0] {
                let c = tracer.corners(cx, cy);
                level0.push(c[0].min(c[1]).min(c[2]).min(c[3]));
            }
        }
        tracer.levels.push(MinLevel { dims: leaves, min_depth: level0 });
        while tracer.levels.last().is_some_and(|l| l.dims[0] > 1 || l.dims[1] > 1) {
            let below = &tracer.levels[tracer.levels.len() - 1];
            let dims = [(below.dims[0] + 1) / 2, (below.dims[1] + 1) / 2];
            let mut min_depth = vec![f32::INFINITY; (dims[0] * dims[1]) as usize];
            for y in 0..below.dims[1] {
                for x in 0..below.dims[0] {
                    let parent = &mut min_depth[((y / 2) * dims[0] + x / 2) as usize];
                    *parent = parent.min(below.min_depth[(y * below.dims[0] + x) as usize]);
                }
            }
            tracer.levels.push(MinLevel { dims, min_depth });
        }
        tracer
    }

    /// The depth samples (world units below the top plane, texel centres, x fastest):
    /// what the GPU layout uploads (`hybrid::gpu_layout`).
    pub fn samples(&self) -> &[f32] {
        &self.samples
    }

    /// The min-depth quadtree, leaves first: per level its (width, height) in cells and
    /// the cells' bounds, x fastest.
    pub fn quadtree(&self) -> impl Iterator<Item = ([i32; 2], &[f32])> {
        self.levels.iter().map(|l| (l.dims, l.min_depth.as_slice()))
    }

    /// Leaf-space shift: 1 on a clamped tile, 0 on a periodic one.
    pub fn leaf_offset(&self) -> i32 {
        self.offset
    }

    /// Depth sample (i, j), wrapped (periodic) or clamped to the edge.
    #[inline]
    fn sample(&self, i: i32, j: i32) -> f32 {
        let (i, j) = if self.periodic { (i.rem_euclid(self.n[0]), j.rem_euclid(self.n[1])) } else { (i.clamp(0, self.n[0] - 1), j.clamp(0, self.n[1] - 1)) };
        self.samples[(j * self.n[0] + i) as usize]
    }

    /// The depths at the corners of leaf (cx, cy): (0,0), (1,0), (0,1), (1,1).
    #[inline]
    fn corners(&self, cx: i32, cy: i32) -> [f32; 4] {
        let (i, j) = (cx - self.offset, cy - self.offset);
        [self.sample(i, j), self.sample(i + 1, j), self.sample(i, j + 1), self.sample(i + 1, j + 1)]
    }

    /// The surface's depth at world (x, y): bilinear between texel centres (wrapped or
    /// clamped), the definition every renderer shares.
    pub fn depth_at(&self, x: f32, y: f32) -> f32 {
        let q = (Vec2::new(x, y) - self.origin) * self.inv_texel - Vec2::splat(0.5);
        let f = q.floor();
        let (s, t) = (q.x - f.x, q.y - f.y);
        let (i, j) = (f.x as i32, f.y as i32);
        let (h00, h10, h01, h11) = (self.sample(i, j), self.sample(i + 1, j), self.sample(i, j + 1), self.sample(i + 1, j + 1));
        (h00 * (1.0 - s) + h10 * s) * (1.0 - t) + (h01 * (1.0 - s) + h11 * s) * t
    }

    /// The leaf-space ray of `ray`, with t = 0 at the world point `ray.at(t0)`.
    pub fn leaf_ray(&self, ray: &Ray, t0: f32) -> HfRay {
        let p = ray.at(t0);
        let q0 = (p.truncate() - self.origin) * self.inv_texel - Vec2::splat(0.5) + Vec2::splat(self.offset as f32);
        HfRay { q0, dq: ray.d.truncate() * self.inv_texel, d0: self.top_z - p.z, dd: -ray.d.z }
    }

    /// The first t in [t_start, t_stop] where `ray` is at least `bias` below the surface
    /// (bias 0 for camera rays; a little for shadow rays leaving the surface). Counts its
    /// traversal steps in `steps` and stops at `max_steps`.
    pub fn trace(&self, ray: &Ray, t_start: f32, t_stop: f32, bias: f32, max_steps: u32, steps: &mut u32) -> HfTrace {
        self.trace_to(ray, t_start, t_stop, bias, max_steps, steps, 0)
    }

    /// [`HeightTracer::trace`] that descends the quadtree no further than level `floor`:
    /// there a node whose bound the ray reaches is a hit on the node's flat top (its
    /// least depth), so the relief finer than 2^floor leaves is flattened to its boxes'
    /// tops — fewer steps where a pixel covers that many texels anyway (`coarse_relief`
    /// of the options). floor 0 is the exact march.
    #[allow(clippy::too_many_arguments)] // trace's arguments and the floor
    pub fn trace_to(&self, ray: &Ray, t_start: f32, t_stop: f32, bias: f32, max_steps: u32, steps: &mut u32, floor: usize) -> HfTrace {
        let r = self.leaf_ray(ray, t_start);
        // Clip to the slab D₀ ≤ D ≤ height_scale: above the shallowest depth D₀ (the
        // quadtree's root bound) no ray meets the surface, below the slab every ray is
        // under it. A ray near the horizon crosses hundreds of tiles above D₀ (a step each).
        let shallowest = self.levels.last().map_or(0.0, |l| l.min_depth[0]).clamp(0.0, self.height_scale);
        let (mut ta, mut tb) = (0.0f32, t_stop - t_start);
        if !clip(r.d0, r.dd, shallowest, self.height_scale, &mut ta, &mut tb) {
            return HfTrace::Miss;
        }
        let floor = floor.min(self.levels.len() - 1);
        let result = if self.periodic { self.trace_periodic(&r, ta, tb, bias, max_steps, steps, floor) } else { self.trace_clamped(&r, ta, tb, bias, max_steps, steps, floor) };
        match result {
            HfTrace::Hit(t) => HfTrace::Hit(t + t_start),
            other => other,
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn trace_clamped(&self, r: &HfRay, mut ta: f32, mut tb: f32, bias: f32, max_steps: u32, steps: &mut u32, floor: usize) -> HfTrace {
        // The tile: q ∈ [½, n + ½] on each axis.
        for axis in 0..2 {
            if !clip(r.q0[axis], r.dq[axis], 0.5, self.n[axis] as f32 + 0.5, &mut ta, &mut tb) {
                return HfTrace::Miss;
            }
        }
        self.traverse(r, ta, tb, bias, max_steps, steps, floor)
    }

    #[allow(clippy::too_many_arguments)]
    fn trace_periodic(&self, r: &HfRay, ta: f32, tb: f32, bias: f32, max_steps: u32, steps: &mut u32, floor: usize) -> HfTrace {
        // Walk the repeats of the tile (cells of n leaves) with a 2D DDA; traverse each.
        let n = Vec2::new(self.n[0] as f32, self.n[1] as f32);
        let q = r.q(ta);
        let mut tile = [0i32; 2];
        for axis in 0..2 {
            let f = (q[axis] / n[axis]).floor();
            // Clamped as the flyaway march clamps (flyaways::TILE_LIMIT): no overflow
            // for rays that meet the slab absurdly far away.
            tile[axis] = f.clamp(-super::flyaways::TILE_LIMIT, super::flyaways::TILE_LIMIT) as i32;
            // On a boundary, moving backwards: the tile behind.
            if q[axis] == f * n[axis] && r.dq[axis] < 0.0 {
                tile[axis] -= 1;
            }
        }
        let mut t = ta;
        let mut walked = 0u32;
        loop {
            let lo = Vec2::new(tile[0] as f32, tile[1] as f32) * n;
            let exits = [axis_exit(r.q0.x, r.dq.x, lo.x, lo.x + n.x), axis_exit(r.q0.y, r.dq.y, lo.y, lo.y + n.y)];
            let t_tile = exits[0].min(exits[1]).min(tb).max(t);
            let local = HfRay { q0: r.q0 - lo, ..*r };
            let floor = if walked >= SKIM_TILES { self.levels.len() - 1 } else { floor };
            walked += 1;
            match self.traverse(&local, t, t_tile, bias, max_steps, steps, floor) {
                HfTrace::Miss => {}
                other => return other,
            }
            // Each tile costs at least one step, so the budget bounds this loop.
            if t_tile >= tb {
                return HfTrace::Miss;
            }
            t = t_tile;
            for axis in 0..2 {
                if exits[axis] <= t_tile {
                    tile[axis] += if r.dq[axis] > 0.0 { 1 } else { -1 };
                }
            }
        }
    }

    /// The quadtree traversal of one tile's leaves over [ta, tb].
    #[allow(clippy::too_many_arguments)]
    fn traverse(&self, r: &HfRay, ta: f32, tb: f32, bias: f32, max_steps: u32, steps: &mut u32, floor: usize) -> HfTrace {
        let top = self.levels.len() - 1;
        let mut level = top;
        let mut cell = [0i32; 2];
        let mut t = ta;
        loop {
            if *steps >= max_steps {
                return HfTrace::StepLimit;
            }
            *steps += 1;
            let size = (1i32 << level) as f32;
            let exits = [
                axis_exit(r.q0.x, r.dq.x, cell[0] as f32 * size, (cell[0] + 1) as f32 * size),
                axis_exit(r.q0.y, r.dq.y, cell[1] as f32 * size, (cell[1] + 1) as f32 * size),
            ];
            let t_exit = exits[0].min(exits[1]).min(tb).max(t);
            let l = &self.levels[level];
            let bound = l.min_depth[(cell[1] * l.dims[0] + cell[0]) as usize];
            // The deepest point of a linear depth profile is at one end of the segment.
            let deepest = r.depth(t).max(r.depth(t_exit));
            if deepest >= bound + bias {
                if level == 0 {
                    if let Some(th) = self.leaf_hit(r, cell, t, t_exit, bias) {
                        return HfTrace::Hit(th);
                    }
                } else if level <= floor.max((*steps / STEPS_PER_FLOOR) as usize) {
                    // The node's flat top: where the (linear) depth reaches its bound.
                    let th = if r.depth(t) >= bound + bias { t } else { (bound + bias - r.d0) / r.dd };
                    return HfTrace::Hit(th.clamp(t, t_exit));
                } else {
                    level -= 1;
                    cell = child(cell, r.q(t), r.dq, (1i32 << level) as f32, self.levels[level].dims);
                    continue;
                }
            }
            // Advance to the neighbouring cell.
            if t_exit >= tb {
                return HfTrace::Miss;
            }
            t = t_exit;
            let old = cell;
            for axis in 0..2 {
                if exits[axis] <= t_exit {
                    cell[axis] += if r.dq[axis] > 0.0 { 1 } else { -1 };
                }
            }
            let dims = self.levels[level].dims;
            if cell[0] < 0 || cell[1] < 0 || cell[0] >= dims[0] || cell[1] >= dims[1] {
                return HfTrace::Miss;
            }
            if level < top && (cell[0] >> 1 != old[0] >> 1 || cell[1] >> 1 != old[1] >> 1) {
                level += 1;
                cell = [cell[0] >> 1, cell[1] >> 1];
            }
        }
    }

    /// The first t in [ta, tb] inside leaf `cell` where g = D − h − bias ≥ 0.
    fn leaf_hit(&self, r: &HfRay, cell: [i32; 2], ta: f32, tb: f32, bias: f32) -> Option<f32> {
        let [h00, h10, h01, h11] = self.corners(cell[0], cell[1]);
        // Bilinear patch h(u, v) = a + b·u + c·v + e·u·v in the leaf's local coordinates.
        let (a, b, c, e) = (h00, h10 - h00, h01 - h00, h00 - h10 - h01 + h11);
        let qa = r.q(ta) - Vec2::new(cell[0] as f32, cell[1] as f32);
        let len = tb - ta;
        let (u0, v0, du, dv) = (qa.x, qa.y, r.dq.x * len, r.dq.y * len);
        // g(s) = g0 + g1·s + g2·s² over s ∈ [0, 1], t = ta + s·len.
        let g0 = r.depth(ta) - (a + b * u0 + c * v0 + e * u0 * v0) - bias;
        let g1 = r.dd * len - (b * du + c * dv + e * (u0 * dv + v0 * du));
        let g2 = -e * du * dv;
        let g = |s: f32| g0 + s * (g1 + s * g2);
        if g0 >= 0.0 {
            return Some(ta);
        }
        // Bracket the first root: the maximum of a concave g, else the far end.
        let mut hi = 1.0f32;
        if g2 < 0.0 {
            let s_max = -g1 / (2.0 * g2);
            if s_max > 0.0 && s_max < 1.0 && g(s_max) >= 0.0 {
                hi = s_max;
            }
        }
        if g(hi) < 0.0 {
            return None;
        }
        let mut lo = 0.0f32;
        for _ in 0..REFINE_STEPS {
            let mid = 0.5 * (lo + hi);
            if g(mid) >= 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Some(ta + hi * len)
    }

    /// Whether the height field blocks the way from surface point `p` toward `wi` (unit)
    /// over `max_dist`. A light at or below the tile's plane is blocked (the cloth is an
    /// opaque sheet); a march that runs out of steps counts as blocked (it is nearly
    /// horizontal, inside the cloth's relief). Returns (blocked, step_limited).
    pub fn occluded(&self, p: Vec3, wi: Vec3, max_dist: f32, max_steps: u32) -> (bool, bool) {
        if wi.z <= 0.0 {
            return (true, false);
        }
        // Leave the surface by a hair and demand a clear margin below it, so that the
        // point's own patch does not shadow it through rounding.
        let scale = self.texel.min_element();
        let ray = Ray::new(p, wi);
        let mut steps = 0;
        match self.trace(&ray, 1e-3 * scale, max_dist, 1e-4 * scale, max_steps, &mut steps) {
            HfTrace::Hit(_) => (true, false),
            HfTrace::Miss => (false, false),
            HfTrace::StepLimit => (true, true),
        }
    }
}

/// Clips [ta, tb] to the t where lo ≤ x0 + dx·t ≤ hi; false if nothing is left.
#[inline]
fn clip(x0: f32, dx: f32, lo: f32, hi: f32, ta: &mut f32, tb: &mut f32) -> bool {
    if dx == 0.0 {
        return x0 >= lo && x0 <= hi && *ta <= *tb;
    }
    let (t0, t1) = ((lo - x0) / dx, (hi - x0) / dx);
    let (t0, t1) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
    *ta = ta.max(t0);
    *tb = tb.min(t1);
    *ta <= *tb
}

/// Where x0 + dx·t leaves [lo, hi] moving along dx (∞ if dx = 0).
#[inline]
fn axis_exit(x0: f32, dx: f32, lo: f32, hi: f32) -> f32 {
    if dx > 0.0 {
        (hi - x0) / dx
    } else if dx < 0.0 {
        (lo - x0) / dx
    } else {
        f32::INFINITY
    }
}

/// The child of `cell` (one level down, children of size `size`) containing `q`; on
/// the midline, the one the ray moves into.
#[inline]
fn child(cell: [i32; 2], q: Vec2, dq: Vec2, size: f32, dims: [i32; 2]) -> [i32; 2] {
    let mut out = [0; 2];
    for axis in 0..2 {
        let mid = (2 * cell[axis] + 1) as f32 * size;
        let upper = q[axis] > mid || (q[axis] == mid && dq[axis] >= 0.0);
        out[axis] = (2 * cell[axis] + upper as i32).min(dims[axis] - 1);
    }
    out
}
