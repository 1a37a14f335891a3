//! Marching the flyaway lists along a ray (the CPU twin of `flyaways.glsl`), front to
//! back, alpha-compositing what it crosses (DESIGN.md §5, §7).
//!
//! The ray walks the level's columns (texel footprints) with a 2D DDA, from where it
//! enters the top plane to where it meets the surface. In each column it walks the list
//! top down (lists go strictly down, so the nodes it meets come in ray order): a node
//! of depth k is the box [column] × [k·s_ℓ, (k+1)·s_ℓ] below the top plane. Crossing
//! it over a path ℓ gives opacity o = 1 − (1 − α)^(g·ℓ/s), s = the voxel's edge, taken as
//! the cube root of its volume (voxels need not be cubes), g the level's path gain at
//! the ray's polar angle (1 without one: [`PathGain`], format 1.9); at level 0, α = 1 and the
//! first node crossed is opaque: the first hit. The march stops once the transmittance
//! falls below [`MIN_TRANSMITTANCE`].
//!
//! Columns are counted in level-0 texel units, within each repeat of the tile: at level
//! ℓ a column is 2^ℓ texels wide, except the last of a tile whose width is not a
//! multiple of 2^ℓ (it ends at the tile's edge, as the level's last texel does).

use glam::{Vec2, Vec3};

use crate::hybrid::{FlyawayNode, Flyaways, HybridModel, PathGain};
use crate::scene::Ray;

/// Below this transmittance the rest of the ray is invisible (≤ 1e-4 of its radiance is
/// dropped); at level 0 the transmittance is exactly 0 after the first node.
pub const MIN_TRANSMITTANCE: f32 = 1e-4;

/// The most tile repeats from the origin a march starts at (see `visit_flyaways`).
pub const TILE_LIMIT: f32 = 16_777_216.0;

/// Where a level's flyaway columns are.
#[derive(Clone, Copy, Debug)]
pub struct FlyawayGrid {
    origin: Vec2,
    /// 1 / the level-0 texel size (HybridModel::inv_texel_size): column coordinates are products.
    inv_texel: Vec2,
    /// Level-0 texels per tile.
    n0: [i32; 2],
    /// Column width in level-0 texels: 2^ℓ.
    span: i32,
    /// Columns per tile at this level.
    dims: [i32; 2],
    top_z: f32,
    /// Voxel depth s_ℓ (world).
    voxel_depth: f32,
    /// Edge used in the opacity exponent: (Δx_ℓ·Δy_ℓ·s_ℓ)^(1/3).
    edge: f32,
    periodic: bool,
    /// The level's gain on the opacity exponent by the ray's polar angle (format 1.9).
    gain: PathGain,
}

impl FlyawayGrid {
    pub fn new(model: &HybridModel, level: usize, periodic: bool) -> FlyawayGrid {
        let texel = model.texel_size();
        let span = 1i32 << level;
        let voxel_depth = model.voxel_depth(level);
        let l = &model.levels[level];
        FlyawayGrid {
            origin: model.tile.origin,
            inv_texel: model.inv_texel_size(),
            n0: [model.width() as i32, model.height_px() as i32],
            span,
            dims: [l.width as i32, l.height as i32],
            top_z: model.tile.top_z,
            voxel_depth,
            edge: (texel.x * texel.y * (span * span) as f32 * voxel_depth).cbrt(),
            periodic,
            gain: l.flyaways.as_ref().and_then(|f| f.path_gain).unwrap_or(PathGain::ONE),
        }
    }
}

/// What a flyaway march returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyawayMarch {
    /// Radiance composited from the nodes crossed (premultiplied by their opacity).
    pub radiance: Vec3,
    /// Transmittance left for what lies behind (the surface).
    pub transmittance: f32,
    /// Columns visited.
    pub columns: u32,
    /// The column budget ran out before `t_end`.
    pub limited: bool,
}

/// Opacity of a voxel of coverage `alpha` crossed over `path` with edge `edge`.
#[inline]
pub fn flyaway_opacity(alpha: f32, path: f32, edge: f32) -> f32 {
    // NaN-aware: a NaN path is no path.
    if path.is_nan() || path <= 0.0 {
        return 0.0;
    }
    if alpha >= 1.0 {
        return 1.0;
    }
    1.0 - (1.0 - alpha).max(0.0).powf(path / edge)
}

/// The column state along one axis: tile repeat `tile`, column `k` within it.
#[derive(Clone, Copy, Debug)]
struct AxisCursor {
    tile: i32,
    k: i32,
}

/// Marches `ray` (unit direction, heading down) through the flyaway lists `f` of grid `g`
/// over [t_start, t_end], calling `shade(index, node, t_in)` for the radiance of each
/// node it crosses (at its entry point; `index` in `f.nodes`), compositing front to back.
pub fn march_flyaways(f: &Flyaways, g: &FlyawayGrid, ray: &Ray, t_start: f32, t_end: f32, max_columns: u32, mut shade: impl FnMut(usize, &FlyawayNode, f32) -> Vec3) -> FlyawayMarch {
    let mut radiance = Vec3::ZERO;
    let mut out = visit_flyaways(f, g, ray, t_start, t_end, max_columns, |index, node, t_in, weight| radiance += weight * shade(index, node, t_in));
    out.radiance = radiance;
    out
}

/// The march of [`march_flyaways`], calling `visit(index, node, t_in, weight)` for each node
/// crossed, `weight` = (transmittance in front of it) · (its opacity): the factor its
/// radiance enters the pixel with. The returned march's `radiance` is zero. The baker's
/// flyaway fit uses the weights directly (the pixel is linear in each node's BRDF).
pub fn visit_flyaways(f: &Flyaways, g: &FlyawayGrid, ray: &Ray, t_start: f32, t_end: f32, max_columns: u32, mut visit: impl FnMut(usize, &FlyawayNode, f32, f32)) -> FlyawayMarch {
    let mut out = FlyawayMarch { radiance: Vec3::ZERO, transmittance: 1.0, columns: 0, limited: false };
    if t_end.is_nan() || t_end <= t_start || ray.d.z >= 0.0 {
        return out;
    }
    // Position in level-0 texel units: u(t) = u0 + du·t.
    let u0 = (ray.o.truncate() - g.origin) * g.inv_texel;
    let du = ray.d.truncate() * g.inv_texel;
    let u_start = u0 + du * t_start;
    let mut cursor = [AxisCursor { tile: 0, k: 0 }; 2];
    for axis in 0..2 {
        let n = g.n0[axis] as f32;
        // Clamped far beyond where f32 positions still resolve a texel (2^24 repeats), so
        // that rays meeting the plane absurdly far away step without integer overflow.
        let mut tile = (u_start[axis] / n).floor().clamp(-TILE_LIMIT, TILE_LIMIT) as i32;
        let mut local = u_start[axis] - tile as f32 * n;
        // On a tile boundary moving backwards: the tile behind.
        if local <= 0.0 && du[axis] < 0.0 {
            tile -= 1;
            local += n;
        }
        let mut k = ((local / g.span as f32).floor() as i32).clamp(0, g.dims[axis] - 1);
        if local == (k * g.span) as f32 && du[axis] < 0.0 && k > 0 {
            k -= 1;
        }
        cursor[axis] = AxisCursor { tile, k };
    }
    // One gain per ray: it depends on the ray's slant alone (HYBRID_FORMAT.md §7.3).
    let gain = g.gain.at(ray.d);
    let depth_at = |t: f32| g.top_z - (ray.o.z + ray.d.z * t);
    let t_at_depth = |d: f32| (g.top_z - d - ray.o.z) / ray.d.z;
    let mut t = t_start;
    while out.columns < max_columns {
        if !g.periodic && (cursor[0].tile != 0 || cursor[1].tile != 0) {
            return out;
        }
        out.columns += 1;
        // This column's extent along each axis, and where the ray leaves it.
        let mut exits = [f32::INFINITY; 2];
        for axis in 0..2 {
            let c = cursor[axis];
            let base = c.tile as f32 * g.n0[axis] as f32;
            let lo = base + (c.k * g.span) as f32;
            let hi = base + ((c.k + 1) * g.span).min(g.n0[axis]) as f32;
            exits[axis] = if du[axis] > 0.0 {
                (hi - u0[axis]) / du[axis]
            } else if du[axis] < 0.0 {
                (lo - u0[axis]) / du[axis]
            } else {
                f32::INFINITY
            };
        }
        let t_next = exits[0].min(exits[1]).min(t_end).max(t);
        let column = (cursor[1].k * g.dims[0] + cursor[0].k) as usize;
        let (d_in, d_out) = (depth_at(t), depth_at(t_next));
        for (index, node) in f.list(column).with_index() {
            let (z0, z1) = f.spreads.as_ref().map_or((0.0, 1.0), |s| s[index].slab());
            let top = (node.depth as f32 + z0) * g.voxel_depth;
            let bottom = (node.depth as f32 + z1) * g.voxel_depth;
            if bottom <= d_in {
                continue;
            }
            if top >= d_out {
                break;
            }
            let t_in = t.max(t_at_depth(top));
            let t_out = t_next.min(t_at_depth(bottom));
            let opacity = flyaway_opacity(node.alpha(), gain * (t_out - t_in), g.edge);
            if opacity > 0.0 {
                visit(index, node, t_in, out.transmittance * opacity);
                out.transmittance *= 1.0 - opacity;
                if out.transmittance < MIN_TRANSMITTANCE {
                    out.transmittance = 0.0;
                    return out;
                }
            }
        }
        if t_next >= t_end {
            return out;
        }
        t = t_next;
        for axis in 0..2 {
            if exits[axis] <= t_next {
                let c = &mut cursor[axis];
                if du[axis] > 0.0 {
                    c.k += 1;
                    if c.k >= g.dims[axis] {
                        c.k = 0;
                        c.tile += 1;
                    }
                } else {
                    c.k -= 1;
                    if c.k < 0 {
                        c.k = g.dims[axis] - 1;
                        c.tile -= 1;
                    }
                }
            }
        }
    }
    out.limited = true;
    out
}
