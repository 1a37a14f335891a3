//! A coarse grid of majorants of σ_t and the 3D DDA that walks a ray through it
//! (Amanatides and Woo 1987), so that free-flight sampling takes long steps through
//! thin regions and none at all through empty ones.
//!
//! Each majorant cell covers a block of voxels; its value bounds σ_t(x, ω) for every
//! point x of the block and every ω: scale · max ρ · max σ(ω). The max runs over the
//! voxels a lookup anywhere in the block can read (one voxel beyond the block for
//! trilinear lookups) plus one more voxel of margin, so rounding in the ray's position
//! can never read a voxel the bound did not see.
//!
//! The slab is thin (z ≪ x, y): the walk keeps, per z layer of blocks, the max over the
//! whole layer, and crosses a layer whose max is zero in one step whatever the ray's
//! horizontal motion. Empty space above the fabric costs one step per empty layer, and
//! a grazing ray in an empty layer of a periodic sheet is not walked tile by tile.

use glam::Vec3;

use super::medium::{Lookup, Medium};

/// Majorants (σ_t per world unit) over blocks of voxels.
pub struct MajorantGrid {
    block: [usize; 3],
    cells: [usize; 3],
    values: Vec<f32>,
    layer_max: Vec<f32>,
    /// Cell edges along each axis in grid units: edges[a][i] = min(i·block, dims).
    edges: [Vec<f32>; 3],
    dims_f: Vec3,
    periodic: bool,
}

/// Default block size in voxels (x, y, z); see `MajorantGrid::new`.
pub const DEFAULT_BLOCK: [usize; 3] = [4, 4, 4];

/// Relative head-room of the majorants over the exact max: rounding in the σ(ω)
/// evaluation can exceed the analytic bound of 1 by an ulp or two.
const HEADROOM: f32 = 1.0 + 1e-5;

impl MajorantGrid {
    /// Builds the grid for a medium with blocks of `block` voxels.
    pub fn new(medium: &Medium<'_>, block: [usize; 3]) -> MajorantGrid {
        use rayon::prelude::*;
        let dims = medium.dims();
        let block = [block[0].clamp(1, dims[0]), block[1].clamp(1, dims[1]), block[2].clamp(1, dims[2])];
        let cells = [dims[0].div_ceil(block[0]), dims[1].div_ceil(block[1]), dims[2].div_ceil(block[2])];
        // Voxels a lookup inside [lo, hi) can read: nearest reads [lo, hi − 1]; trilinear
        // reads [lo − 1, hi]; one more voxel of margin on each side.
        let reach: i64 = match medium.lookup() {
            Lookup::Nearest => 1,
            Lookup::Trilinear => 2,
        };
        let periodic = medium.is_periodic();
        let bound = medium.scale() * medium.max_projected_area() * HEADROOM;
        let values: Vec<f32> = (0..cells[0] * cells[1] * cells[2])
            .into_par_iter()
            .map(|c| {
                let (cx, cy, cz) = (c % cells[0], (c / cells[0]) % cells[1], c / (cells[0] * cells[1]));
                let range = |a: usize, ci: usize, wrap: bool| -> Vec<usize> {
                    let lo = (ci * block[a]) as i64 - reach;
                    let hi = (((ci + 1) * block[a]).min(dims[a])) as i64 - 1 + reach;
                    let n = dims[a] as i64;
                    let mut v: Vec<usize> = (lo..=hi).map(|i| if wrap { i.rem_euclid(n) } else { i.clamp(0, n - 1) } as usize).collect();
                    v.sort_unstable();
                    v.dedup();
                    v
                };
                let (xs, ys, zs) = (range(0, cx, periodic), range(1, cy, periodic), range(2, cz, false));
                let mut max_rho = 0.0f32;
                for &z in &zs {
                    for &y in &ys {
                        let row = dims[0] * (y + dims[1] * z);
                        for &x in &xs {
                            max_rho = max_rho.max(medium.voxel_density(row + x));
                        }
                    }
                }
                max_rho * bound
            })
            .collect();
        let layer = cells[0] * cells[1];
        let layer_max = (0..cells[2]).map(|z| values[z * layer..(z + 1) * layer].iter().copied().fold(0.0, f32::max)).collect();
        let edges = [0, 1, 2].map(|a| (0..=cells[a]).map(|i| ((i * block[a]).min(dims[a])) as f32).collect::<Vec<f32>>());
        MajorantGrid { block, cells, values, layer_max, edges, dims_f: medium.dims_f(), periodic }
    }

    pub fn block(&self) -> [usize; 3] {
        self.block
    }

    pub fn cells(&self) -> [usize; 3] {
        self.cells
    }

    #[inline]
    pub fn value(&self, x: usize, y: usize, z: usize) -> f32 {
        self.values[x + self.cells[0] * (y + self.cells[1] * z)]
    }

    /// The largest majorant.
    pub fn max(&self) -> f32 {
        self.layer_max.iter().copied().fold(0.0, f32::max)
    }

    /// Starts a walk along `g0 + t·dg` (grid coordinates, t in world units) over
    /// [t0, t1], which must lie inside the slab (see `Medium::clip`).
    pub fn walk(&self, g0: Vec3, dg: Vec3, t0: f32, t1: f32) -> Walk<'_> {
        let mut w = Walk {
            grid: self,
            g0,
            dg,
            inv_d: dg.recip(),
            step: [step_of(dg.x), step_of(dg.y), step_of(dg.z)],
            t: t0,
            t_end: t1,
            local: [0; 3],
            tile: [0; 3],
            t_next: [f32::INFINITY; 3],
            steps: 0,
        };
        w.seek(t0);
        w
    }

    /// Which cell along axis `a` contains grid coordinate `g` of the base tile.
    #[inline]
    fn cell_of(&self, a: usize, g: f32) -> usize {
        ((g / self.block[a] as f32).floor().max(0.0) as usize).min(self.cells[a] - 1)
    }
}

#[inline]
fn step_of(d: f32) -> i8 {
    if d > 0.0 {
        1
    } else if d < 0.0 {
        -1
    } else {
        0
    }
}

/// One piece of a ray with a constant majorant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub t0: f32,
    pub t1: f32,
    /// σ̄ per world unit (0 in empty blocks).
    pub majorant: f32,
}

/// Most cells one walk may visit before it gives up (see `Walk::truncated`).
pub const MAX_WALK_STEPS: u32 = 1 << 22;

/// A ray walking through the majorant grid, one cell at a time.
pub struct Walk<'g> {
    grid: &'g MajorantGrid,
    g0: Vec3,
    dg: Vec3,
    inv_d: Vec3,
    step: [i8; 3],
    t: f32,
    t_end: f32,
    /// Cell within the tile, and the tile (periodic x, y only; always 0 for z).
    local: [usize; 3],
    tile: [i64; 3],
    /// Parameter t at which the ray leaves the current cell along each axis.
    t_next: [f32; 3],
    steps: u32,
}

impl Walk<'_> {
    /// Locates the cell at parameter `t` and the distances to its faces.
    fn seek(&mut self, t: f32) {
        for a in 0..3 {
            self.seek_axis(a, t);
        }
    }

    fn seek_axis(&mut self, a: usize, t: f32) {
        let g = self.g0[a] + t * self.dg[a];
        let dims = self.grid.dims_f[a];
        let (tile, local_g) = if self.grid.periodic && a < 2 {
            let tile = (g / dims).floor();
            (tile as i64, g - tile * dims)
        } else {
            (0, g)
        };
        self.tile[a] = tile;
        self.local[a] = self.grid.cell_of(a, local_g);
        self.t_next[a] = self.face_t(a);
    }

    /// Parameter of the face through which the ray leaves the current cell along `a`.
    #[inline]
    fn face_t(&self, a: usize) -> f32 {
        match self.step[a] {
            0 => f32::INFINITY,
            s => {
                let edge = self.grid.edges[a][self.local[a] + (s > 0) as usize];
                let g = self.tile[a] as f32 * self.grid.dims_f[a] + edge;
                (g - self.g0[a]) * self.inv_d[a]
            }
        }
    }

    /// Moves to the neighbouring cell along `a`; false when the ray leaves the grid.
    #[inline]
    fn advance(&mut self, a: usize) -> bool {
        let n = self.grid.cells[a];
        if self.step[a] > 0 {
            if self.local[a] + 1 < n {
                self.local[a] += 1;
            } else if self.grid.periodic && a < 2 {
                self.local[a] = 0;
                self.tile[a] += 1;
            } else {
                return false;
            }
        } else if self.local[a] > 0 {
            self.local[a] -= 1;
        } else if self.grid.periodic && a < 2 {
            self.local[a] = n - 1;
            self.tile[a] -= 1;
        } else {
            return false;
        }
        self.t_next[a] = self.face_t(a);
        true
    }

    /// Whether the walk stopped because it visited `MAX_WALK_STEPS` cells (a ray
    /// running almost parallel to the sheet through an almost empty layer).
    pub fn truncated(&self) -> bool {
        self.steps >= MAX_WALK_STEPS
    }
}

impl Iterator for Walk<'_> {
    type Item = Segment;

    #[inline]
    fn next(&mut self) -> Option<Segment> {
        loop {
            if self.t >= self.t_end || self.steps >= MAX_WALK_STEPS {
                return None;
            }
            self.steps += 1;
            let [x, y, z] = self.local;
            if self.grid.layer_max[z] == 0.0 {
                // Cross the empty layer in one step, then find x and y again there.
                let t = self.t_next[2].max(self.t);
                if t >= self.t_end || !self.advance(2) {
                    self.t = self.t_end;
                    return None;
                }
                self.t = t;
                self.seek_axis(0, t);
                self.seek_axis(1, t);
                continue;
            }
            let a = if self.t_next[0] <= self.t_next[1] && self.t_next[0] <= self.t_next[2] {
                0
            } else if self.t_next[1] <= self.t_next[2] {
                1
            } else {
                2
            };
            // (max: rounding can put a face a hair behind the current t after a seek)
            let t1 = self.t_next[a].min(self.t_end).max(self.t);
            let seg = Segment { t0: self.t, t1, majorant: self.grid.value(x, y, z) };
            self.t = t1;
            if t1 < self.t_end && !self.advance(a) {
                self.t = self.t_end;
            }
            if seg.t1 > seg.t0 {
                return Some(seg);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::medium::MediumOptions;
    use crate::volume::{Aabb, FabricVolume, MaterialParams, Voxel};

    fn volume() -> FabricVolume {
        // 16×12×8, density in a band z ∈ [2, 5], random-ish values.
        let mut v = FabricVolume::new([16, 12, 8], Aabb::new(Vec3::ZERO, Vec3::new(16.0, 12.0, 4.0)), MaterialParams { density_scale: 1.5, roughness: 0.3 });
        for z in 2..6 {
            for y in 0..12 {
                for x in 0..16 {
                    let rho = ((x * 7 + y * 13 + z * 5) % 11) as f32 * 0.5;
                    v.set(x, y, z, Voxel::pack(rho, Vec3::ONE, Vec3::X));
                }
            }
        }
        v
    }

    /// Along many rays, every point's σ_t is below the majorant of the segment that
    /// covers it, the segments tile the clipped interval, and they come in order.
    #[test]
    fn majorants_bound_sigma_t_along_rays() {
        let v = volume();
        for (lookup, periodic, block) in [(Lookup::Trilinear, false, [4, 4, 4]), (Lookup::Trilinear, true, [3, 5, 2]), (Lookup::Nearest, true, [8, 8, 4])] {
            let m = Medium::new(&v, MediumOptions { lookup, periodic, ..Default::default() }).unwrap();
            let grid = MajorantGrid::new(&m, block);
            let mut rng = crate::reference::rng::Rng::new(5, 0, 0);
            for _ in 0..300 {
                let d = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5).normalize();
                let o = Vec3::new(rng.next_f32() * 16.0, rng.next_f32() * 12.0, rng.next_f32() * 4.0);
                let (g0, dg) = (m.to_grid(o), d / v.voxel_size());
                let Some((t0, t1)) = m.clip(g0, dg, 0.0, 40.0) else { continue };
                let mut t = t0;
                let mut walk = grid.walk(g0, dg, t0, t1);
                for seg in walk.by_ref() {
                    assert!((seg.t0 - t).abs() <= 1e-4 * (1.0 + t.abs()), "gap: {t} → {}", seg.t0);
                    for k in 0..=8 {
                        let tt = seg.t0 + (seg.t1 - seg.t0) * k as f32 / 8.0;
                        let s = m.sigma_t(g0 + tt * dg, d);
                        assert!(s <= seg.majorant, "{lookup:?} periodic={periodic}: σ_t {s} > majorant {} at t {tt}", seg.majorant);
                    }
                    t = seg.t1;
                }
                assert!(!walk.truncated());
                assert!((t - t1).abs() <= 1e-4 * (1.0 + t1.abs()), "walk ended at {t}, slab at {t1}");
            }
        }
    }

    #[test]
    fn empty_layers_are_crossed_in_one_step() {
        // Density in z ∈ [2, 5] of 12 layers: layers ≥ 8 are empty even counting the
        // trilinear reach and margin.
        let mut v = FabricVolume::new([16, 12, 12], Aabb::new(Vec3::ZERO, Vec3::new(16.0, 12.0, 6.0)), MaterialParams::default());
        for z in 2..6 {
            for y in 0..12 {
                for x in 0..16 {
                    v.set(x, y, z, Voxel::pack(1.0, Vec3::ONE, Vec3::X));
                }
            }
        }
        let m = Medium::new(&v, MediumOptions { periodic: true, ..Default::default() }).unwrap();
        let grid = MajorantGrid::new(&m, [4, 4, 1]);
        // A nearly horizontal ray high in the empty top layer climbs out after 1e4 tiles
        // of horizontal travel, yet the walk takes one step per layer.
        let d = Vec3::new(1.0, 0.3, 1e-5).normalize();
        let g0 = Vec3::new(1.0, 1.0, 10.5);
        let (t0, t1) = m.clip(g0, d / v.voxel_size(), 0.0, f32::INFINITY).unwrap();
        let mut walk = grid.walk(g0, d / v.voxel_size(), t0, t1);
        assert_eq!(walk.by_ref().count(), 0);
        assert!(walk.steps <= 3, "{} steps", walk.steps);
        // Going down instead, it reaches the fabric layers after crossing the empty ones.
        let d = Vec3::new(1.0, 0.3, -1e-3).normalize();
        let (t0, t1) = m.clip(g0, d / v.voxel_size(), 0.0, f32::INFINITY).unwrap();
        let first = grid.walk(g0, d / v.voxel_size(), t0, t1).next().unwrap();
        assert!(first.majorant > 0.0 && (g0 + first.t0 * d / v.voxel_size()).z < 8.0 + 1e-3, "{first:?}");
    }
}
