//! Which levels of the mip chain shade a pixel and through which grids: the levels of a
//! footprint (Vulkan's anisotropic rule), the coarse filter's box grid of lookups one
//! level finer, level 0's grid of nearest texels, and the flyaways' grids of parallel
//! rays (DESIGN.md §7; runtime/HYBRID_FORMAT.md §6). Pure functions of a footprint:
//! `Scene::level_mix_axes` (render.rs) measures the footprint and calls them.
//!
//! Twin: shaders/common/level.glsl, name for name (`LevelMix`, `linear_levels`,
//! `box_grid`, `grid_taps`, `fly_box_grid`, `fine_grid_spread`, `level0_grid_taps`,
//! `level0_reach_weight`, `fine_grid_traced` and their constants).

use glam::Vec2;

/// The levels that shade a ray: `lo` with weight 1 − `weight`, `hi` with `weight`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelMix {
    pub lo: usize,
    pub hi: usize,
    pub weight: f32,
    /// Anisotropic filtering of coarse levels: `taps` lookups spread evenly over
    /// `axis` (world x–y, the footprint's major axis), centred on the hit.
    pub axis: Vec2,
    pub taps: u32,
    /// Lookups across the footprint: `taps_minor` spread over `minor_axis` for each of
    /// the `taps` along `axis` (1: the major axis alone).
    pub minor_axis: Vec2,
    pub taps_minor: u32,
    /// The flyaway levels (lo, hi, weight of hi): from the isotropic footprint without
    /// [`FILTER_OFFSET`] — voxels are not filtered like texels, and a finer level than
    /// the pixel aliases their coverage — or, through a box grid, finer
    /// ([`fly_box_grid`]).
    pub fly: (usize, usize, f32),
    /// The flyaway levels (lo, hi, weight of hi) a surface hit's shadow is marched
    /// through (`Scene::flyaway_shadow_mixed`, format 1.13): the whole footprint's
    /// ([`shadow_lambda`]), one march standing for all of its texels.
    pub shadow: (usize, usize, f32),
    /// The flyaways' box grid: `fly_taps.0` × `fly_taps.1` parallel rays spread over the
    /// spans `fly_axes` (world x–y; the footprint's major axis first), each marching
    /// `fly`'s levels ((1, 1): the ray alone).
    pub fly_axes: (Vec2, Vec2),
    pub fly_taps: (u32, u32),
    /// Level 0's grid where its footprint spans more than a quarter texel
    /// ([`fine_grid_spread`]), up to [`LEVEL0_REACH`] texels and blended with level 1
    /// beyond ([`level0_reach_weight`]): `fine_taps.0` ×
    /// `fine_taps.1` nearest-texel lookups spread over `fine_axes` (world x–y; the
    /// footprint's major axis first) beside the hit ((1, 1): the hit's texel alone).
    pub fine_axes: (Vec2, Vec2),
    pub fine_taps: (u32, u32),
    /// `CoarseFilter::Split` and `SplitShaded`: the finer grid of rays that gives the
    /// flyaways' coverage (and with `SplitShaded` the lights' light; None: the shading
    /// grid's own).
    pub cover: Option<FlyCover>,
}

/// The flyaways' coverage grid of `CoarseFilter::Split`: `taps.0` × `taps.1` parallel
/// rays over `axes` (as [`tap_offset`] places them), each marching the levels `fly`
/// (lo, hi, weight of hi) for its transmittance alone, unshaded (`SplitShaded`: shaded
/// with the lights).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyCover {
    pub fly: (usize, usize, f32),
    pub axes: (Vec2, Vec2),
    pub taps: (u32, u32),
}

impl LevelMix {
    pub fn single(level: usize) -> LevelMix {
        LevelMix { lo: level, hi: level, weight: 0.0, axis: Vec2::ZERO, taps: 1, minor_axis: Vec2::ZERO, taps_minor: 1, fly: (level, level, 0.0), shadow: (level, level, 0.0), fly_axes: (Vec2::ZERO, Vec2::ZERO), fly_taps: (1, 1), fine_axes: (Vec2::ZERO, Vec2::ZERO), fine_taps: (1, 1), cover: None }
    }
}

/// Levels ⌊λ⌋ and ⌊λ⌋ + 1 with the weight of the second, clamped to 0..=last.
pub(crate) fn linear_levels(lambda: f32, last: usize) -> (usize, usize, f32) {
    if !(lambda > 0.0) {
        return (0, 0, 0.0);
    }
    let lo = lambda.floor();
    if lo as usize >= last { (last, last, 0.0) } else { (lo as usize, lo as usize + 1, lambda - lo) }
}

/// Most lookups of the anisotropic filter (a GPU's maxSamplerAnisotropy is 16).
pub const MAX_ANISOTROPY: u32 = 8;

/// Added to λ so that a coarse level's filter is as wide as the pixel's: a bilinear
/// lookup of box-filtered texels of size T has variance T²/12 + T²/6 = T²/4, a pixel's
/// box of size P has P²/12, equal at T = P/√3: λ − ½·log2 3. Measured on a twill far
/// view at 30° azimuth (16 px across a 128² tile): 22.6% without it, see
/// baker/PREFILTER_MEASUREMENTS.md.
pub const FILTER_OFFSET: f32 = -0.792_481_25;

/// Lookups per axis of the flyaways' box grid (`fly_box_grid`, `CoarseFilter::fly_grid`),
/// and of the grid that measures level 0's reach ([`level0_reach_weight`]): footprints
/// are measured in its lookups, whatever grid the surface has.
pub const FILTER_GRID: u32 = 2;

/// Lookups per axis of the surface's box grid at coarse levels (`box_grid`,
/// `CoarseFilter::grid`): 3 since 2026-12-07 (2 before). Coarse texels are fits of their
/// footprints, less faithful the coarser (satin's 128-cluster chain: fit error 9–11% per
/// texel with two lobes); a 3 × 3 grid reads up to log2(3/2) ≈ 0.58 level finer than a
/// 2 × 2 one at the same footprint. Satin's and twill's distance sweeps at the bake's default K went from
/// 4.4–5.4% and 3.5–5.2% to 3.9–5.0% and 3.1–4.7% (baker/PREFILTER_MEASUREMENTS.md,
/// "What kept satin and twill at the default K above 5%, and a 3 × 3 surface grid").
pub const SURFACE_GRID: u32 = 3;

/// The box filter's grid of lookups: `taps_major` × `taps_minor` bilinear lookups at
/// level `lambda`, spread over spans (level-0 texels) of the footprint's two axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxGrid {
    pub lambda: f32,
    pub taps_major: u32,
    pub taps_minor: u32,
    pub span_major: f32,
    pub span_minor: f32,
}

/// A pixel's box is not a texel's square: where its rows run at an angle to the tile
/// (a far view at 30° azimuth), one bilinear lookup as wide as the pixel misses the
/// box's shape, though not its variance. A grid of `FILTER_GRID` lookups per axis (N·G
/// along the major axis) one level finer, spread so that each axis's variance — grid
/// s²(G² − 1)/12 plus a lookup's T²/4, T = 2^λ — is still the pixel's P²/12, follows the
/// box more closely (baker/PREFILTER_MEASUREMENTS.md, "The box filter"). Level 0 is
/// never read through the grid (it is shaded by its nearest texel), so λ stops at 1 and
/// the spread shrinks to 0 as λ of the one-lookup rule falls to 1: the filter's width
/// is continuous in distance. None: the one-lookup rule (`lambda` ≤ 1, or `grid` ≤ 1).
/// Footprint lengths in level-0 texels; `n` the anisotropic lookups, `lambda` their level,
/// `grid` the lookups per axis ([`CoarseFilter::grid`](super::CoarseFilter::grid)).
pub fn box_grid(major: f32, minor: f32, n: u32, lambda: f32, bias: f32, grid: u32) -> Option<BoxGrid> {
    if grid <= 1 || !(lambda > 1.0) {
        return None;
    }
    let taps_major = grid_taps(n, grid);
    let level = ((major / taps_major as f32).log2() + FILTER_OFFSET + bias).max(1.0);
    let kernel = (2.0 * level).exp2() / 4.0;
    let scale = (2.0 * bias).exp2();
    // s²(G² − 1)/12 = P²/12 − T²/4, as a span s·G.
    let span = |p: f32, g: u32| -> f32 {
        if g <= 1 {
            return 0.0;
        }
        let s2 = (p * p * scale / 12.0 - kernel).max(0.0) * 12.0 / (g * g - 1) as f32;
        s2.sqrt() * g as f32
    };
    let span_major = span(major, taps_major);
    let span_minor = span(minor, grid);
    // A spread of (nearly) nothing is one lookup.
    let (taps_major, span_major) = if span_major > 1e-3 { (taps_major, span_major) } else { (1, 0.0) };
    let (taps_minor, span_minor) = if span_minor > 1e-3 { (grid, span_minor) } else { (1, 0.0) };
    Some(BoxGrid { lambda: level, taps_major, taps_minor, span_major, span_minor })
}

/// Lookups of the box grid along a footprint's major axis: G per anisotropic lookup,
/// at most [`MAX_ANISOTROPY`] (or N). The flyaways' grid marches at their level.
/// Twin: `grid_taps` in shaders/common/level.glsl.
pub fn grid_taps(n: u32, grid: u32) -> u32 {
    (n * grid).min(MAX_ANISOTROPY.max(n))
}

/// Where lookup (or ray) `tap` of a grid lies: `taps` evenly over the span `axis`
/// (world x–y) by `taps_minor` over `minor_axis`, centred on the hit. The surface's grid
/// and the flyaways' rays share it. Twin: `tap_offset` in shaders/common/shading.glsl.
pub fn tap_offset(axis: Vec2, taps: u32, minor_axis: Vec2, taps_minor: u32, tap: u32) -> Vec2 {
    let (ka, kb) = (tap % taps, tap / taps);
    axis * ((ka as f32 + 0.5) / taps as f32 - 0.5) + minor_axis * ((kb as f32 + 0.5) / taps_minor as f32 - 0.5)
}

/// Most flyaway rays along a footprint's major axis per ray across it. A grazing ray
/// already runs along that axis through the voxels it crosses: 2·G rays along it came
/// within 0.4 points of the surface's N·G (felt at 70°, 16 px: 23.1% against 22.7% with
/// 6; twill and satin within 0.2) for a third fewer marches, G alone lost up to 3
/// points (baker/PREFILTER_MEASUREMENTS.md, "Anisotropic flyaway rays").
pub const FLY_MAX_ANISOTROPY: u32 = 2;

/// The flyaways' box grid: the level its rays march, the fraction of the pixel's
/// footprint they spread over, and how many run along its major and minor axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyGrid {
    pub lambda: f32,
    pub spread: f32,
    pub taps_major: u32,
    pub taps_minor: u32,
}

/// The flyaways' box grid for a footprint of `major` level-0 texels along its major
/// axis, `n` anisotropic lookups (the surface's N = ⌈major/minor⌉), `bias` and `grid`
/// rays per axis. A voxel as wide as the pixel, met by one ray, is a nearest-texel
/// lookup of its coverage: a pixel turned against the voxels' grid sees parts of four
/// (baker/PREFILTER_MEASUREMENTS.md, "The box filter"), and a level-0 fibre a voxel
/// wide, seen at ½–2 texels per pixel, is point-sampled. The rays march the level of
/// the surface's lookups, major/min(N·G, 8), down to level 0: a grazing pixel's
/// footprint is N times longer than wide, and voxels as wide as its long side (the
/// isotropic level, log2 major) blur what the short side resolves (felt at 70°, 16 px:
/// 31.8% → 23.1%; "Anisotropic flyaway rays"); min(N, [`FLY_MAX_ANISOTROPY`])·G of them
/// run along the major axis and G across it. They spread as level 0's grid of the
/// surface does ([`fine_grid_spread`] of major/N, about the minor axis): from nothing
/// at a quarter texel to the whole footprint at half a texel, so that the filter is
/// continuous in distance; closer, one ray at that level (without a grid, one ray at
/// λ = log2 major). Until the distance sweep's felt showed otherwise, the grid started
/// at λ = 1 at level 1, one ray nearer: a coarse flyaway level stood in for level 0's
/// fibres at 1–4 texels per pixel, and one ray point-sampled them nearer still (felt's
/// steps at ½ / 0.91 / 1.64 / 2.97 texels per pixel: 14.3 / 15.6 / 13.2 / 9.5% →
/// 4.5 / 5.0 / 5.9 / 6.9%; "Flyaways through a grid from a quarter texel across").
pub fn fly_box_grid(major: f32, n: u32, bias: f32, grid: u32) -> FlyGrid {
    let lambda = major.log2() + bias;
    if grid <= 1 {
        return FlyGrid { lambda, spread: 0.0, taps_major: 1, taps_minor: 1 };
    }
    // The level of N·G lookups along the major axis (at most 8, as the surface's),
    // about the minor axis over G: voxels 1/G of a round footprint (G = 2, the default:
    // one level finer, the surface grid's level; `FLY_FINE_GRID`: two). The one ray
    // short of a quarter texel marches it too, so that the grid grows out of it.
    let n = n.max(1);
    let taps = grid_taps(n, grid);
    let finer = (lambda - (grid as f32).log2() - (taps as f32 / grid as f32).log2()).max(0.0);
    let spread = fine_grid_spread(major / n as f32);
    if !(spread > 0.0) {
        return FlyGrid { lambda: finer, spread: 0.0, taps_major: 1, taps_minor: 1 };
    }
    FlyGrid { lambda: finer, spread, taps_major: n.min(FLY_MAX_ANISOTROPY) * grid, taps_minor: grid }
}

/// The ray of a flyaway grid (`taps` × `taps_minor` over `axis`, `minor_axis`, as
/// [`tap_offset`] places them) whose cell holds the point at `offset` from the grid's
/// centre: its coordinates along the two axes, clamped to the grid.
pub fn fly_cell(offset: Vec2, axis: Vec2, taps: u32, minor_axis: Vec2, taps_minor: u32) -> u32 {
    // offset = axis·s + minor_axis·r, s and r in [−½, ½] over the grid.
    let det = axis.x * minor_axis.y - axis.y * minor_axis.x;
    // Nearly parallel axes (|sin| under 1e-3) are taken as parallel: their determinant
    // would be rounding.
    let (s, r) = if det.abs() > 1e-3 * axis.length() * minor_axis.length() && det.abs() > 0.0 {
        ((offset.x * minor_axis.y - offset.y * minor_axis.x) / det, (axis.x * offset.y - axis.y * offset.x) / det)
    } else {
        // Parallel or empty axes: along the longer one alone.
        let (a, n) = if axis.length_squared() >= minor_axis.length_squared() { (axis, 0) } else { (minor_axis, 1) };
        let u = if a.length_squared() > 0.0 { offset.dot(a) / a.length_squared() } else { 0.0 };
        if n == 0 { (u, 0.0) } else { (0.0, u) }
    };
    // A point on a cell border (a surface grid's lookups often are: both grids are
    // symmetric about the hit) goes to the cell after it, whatever the rounding: the
    // border is moved a thousandth of a cell back, where nothing lies by symmetry.
    let cell = |u: f32, n: u32| {
        let c = ((u + 0.5) * n as f32 + 1e-3).floor();
        (if c.is_nan() { 0.0 } else { c.clamp(0.0, (n.max(1) - 1) as f32) }) as u32
    };
    cell(s, taps) + taps * cell(r, taps_minor)
}

/// The level (before [`linear_levels`]) whose flyaways a surface hit's shadow is marched
/// through, for a footprint of `major` × `minor` level-0 texels: the level of its
/// geometric mean width, log2 √(major · minor) + bias, where one march stands for the
/// mean of the footprint's shadows (format 1.13; baker/FIT_MEASUREMENTS.md, "The
/// flyaways' shadow on the surface"). Twin: `shadow_lambda` in shaders/common/level.glsl.
pub fn shadow_lambda(major: f32, minor: f32, bias: f32) -> f32 {
    // Felt 64², far views at 16 px (4 texels per pixel), 0° / 45° / 70°: 14.1 / 10.5 /
    // 9.5% off the supersampled level 0 at this level; 15.8 / 13.6 / 11.0% one level
    // finer, 15.3 / 12.6 / 10.9% one coarser; 23.3 / 24.9 / 20.4% with level 0's alone.
    0.5 * (major.log2() + minor.max(1e-6).log2()) + bias
}

/// Rays per axis of the flyaways' grid under `CoarseFilter::Fine`: voxels a quarter of
/// a round footprint, rays at their spacing. The presets' far views summed: 170.6
/// points with 2 (the box filter), 154.3 with 3, 149.4 with 4, at 1.4–2× and 2–3× a
/// wholly distant frame's CPU time (baker/PREFILTER_MEASUREMENTS.md, "A finer box for
/// the flyaways").
pub const FLY_FINE_GRID: u32 = 4;

/// Level 0's grid of nearest texels starts to spread at a footprint (minor axis) of
/// this many texels: closer views point-sample the hit's texel, bit for bit as before.
pub const FINE_GRID_FROM: f32 = 0.25;
/// ... and spans the whole footprint from this many texels on. The distance sweep's
/// nearest steps (½ to 1.6 texels per pixel, twill 128²) went from 12.9 / 11.5 / 9.0%
/// with the grid from one texel across to 9.0 / 8.9 / 8.5%
/// (baker/PREFILTER_MEASUREMENTS.md, "Level 0 through a grid from a quarter texel
/// across").
pub const FINE_GRID_FULL: f32 = 0.5;

/// How far level 0's grid spreads over a footprint whose minor axis spans `minor`
/// level-0 texels: 0 up to [`FINE_GRID_FROM`], 1 from [`FINE_GRID_FULL`], linear
/// between. Twin: `fine_grid_spread` in shaders/common/level.glsl.
pub fn fine_grid_spread(minor: f32) -> f32 {
    ((minor - FINE_GRID_FROM) / (FINE_GRID_FULL - FINE_GRID_FROM)).clamp(0.0, 1.0)
}

/// Level 0 is read through its own grid of nearest texels up to footprints this many
/// level-0 texels across (measured by [`FILTER_GRID`] lookups per round footprint,
/// whatever the surface's grid, each spanning up to `LEVEL0_REACH / FILTER_GRID` texels), and level 1
/// only beyond. At 2–4 texels per pixel the prefiltered level 1 is the coarse fit of a
/// 2×2 footprint, bilinearly blurred over twice the pixel's width, while a 4×4 grid of
/// level 0's own texels is the pixel's box: 32 px far views (4 texels per pixel, chain at
/// 1 sample) satin 8.2 / 8.0 / 12.2% → 6.9 / 4.7 / 11.9% at 0° / 45° / 70°, twill 6.2 /
/// 4.6 / 6.7 → 5.2 / 3.4 / 6.8%, the surface alone (satin, 0°) 7.8 → 2.5%; the lookups
/// read where the flyaway rays landed, so they cost shading, not traces
/// (baker/PREFILTER_MEASUREMENTS.md, "Level 0 up to four texels per pixel").
pub const LEVEL0_REACH: f32 = 4.0;

/// Most lookups per axis of level 0's grid, and in all (shaders/common/level.glsl's
/// `LEVEL0_GRID_MAX`, `LEVEL0_TAPS_MAX`). With 16 in all, a footprint four texels
/// across had no lookups to spare along its major axis: satin's 32 px far view at 70°
/// (4 × 11.7 texels) read a 4 × 4 grid, 5.3% off; with 32, 4 × 8 lookups, 4.4%
/// (baker/PREFILTER_MEASUREMENTS.md, "Level 0's grid along grazing footprints").
pub const LEVEL0_GRID_MAX: u32 = 4;
pub const LEVEL0_TAPS_MAX: u32 = 32;
/// Most lookups of a surface grid, coarse ([`MAX_ANISOTROPY`] · [`SURFACE_GRID`]) or
/// level 0's ([`LEVEL0_TAPS_MAX`]) (shaders/common/shading.glsl's `MAX_SURFACE_TAPS`).
pub const MAX_SURFACE_TAPS: u32 = if MAX_ANISOTROPY * SURFACE_GRID > LEVEL0_TAPS_MAX { MAX_ANISOTROPY * SURFACE_GRID } else { LEVEL0_TAPS_MAX };

/// The lookups of level 0's grid over a footprint whose minor axis spans `minor`
/// level-0 texels, with `n` anisotropic lookups and `grid` lookups per axis of the box
/// filter: about one per texel across (⌈minor⌉, from `grid` to [`LEVEL0_GRID_MAX`]) and
/// n times as many along the major axis, at most [`LEVEL0_TAPS_MAX`] in all. Up to
/// `grid` texels across this is n·`grid` × `grid`, the box grid's (`grid_taps`) where
/// that is within its cap of [`MAX_ANISOTROPY`] along. Twin:
/// `level0_grid_taps` in shaders/common/level.glsl.
pub fn level0_grid_taps(minor: f32, n: u32, grid: u32) -> (u32, u32) {
    let across = if minor > 0.0 { (minor.ceil().min(LEVEL0_GRID_MAX as f32) as u32).max(grid) } else { grid };
    let along = (n.max(1) * across).min((LEVEL0_TAPS_MAX / across).max(across));
    (along, across)
}

/// The weight of level 1 (read through its box grid) over level 0's grid, for a box
/// grid whose lookups' level before clamping is `lambda_b`
/// (log2(major / lookups along it) + [`FILTER_OFFSET`] + bias): 0 while those lookups span
/// at most `LEVEL0_REACH / FILTER_GRID` texels, 1 where the box grid's level reaches 1,
/// linear in the level between (footprints of 4 to 6.9 texels for a round one), so that
/// the switch from level 0's data to level 1's is a blend. Twin: `level0_reach_weight` in
/// shaders/common/level.glsl.
pub fn level0_reach_weight(lambda_b: f32) -> f32 {
    let from = (LEVEL0_REACH / FILTER_GRID as f32).log2() + FILTER_OFFSET;
    let w = (lambda_b - from) / (1.0 - from);
    if w.is_nan() { 1.0 } else { w.clamp(0.0, 1.0) }
}

/// Level 0's grid traces each lookup's own parallel ray to where it meets the height
/// field once the grid spans this many texels (along its longer axis); a narrower grid,
/// a close-up's, reads its lookups beside the hit, on the plane. Within half a texel the
/// traced points changed none of the sweep's near steps (0.3–0.9 texels per pixel, all
/// three presets, to 0.01 points) and the synthetic golden view by 10.28 → 10.04%
/// against 8 × 8 samples, while lavapipe's twill frame at 0.375 texels per pixel went
/// from 75 to 42 ms (baker/PREFILTER_MEASUREMENTS.md, "Level 0's grid traced from half
/// a texel across").
pub const FINE_TRACE_FROM: f32 = 0.5;

/// Whether level 0's grid over `fine_axes` (world x–y) traces its lookups
/// ([`FINE_TRACE_FROM`]). Twin: `fine_grid_traced` in shaders/common/level.glsl.
pub fn fine_grid_traced(fine_axes: (Vec2, Vec2), inv_texel: Vec2) -> bool {
    (fine_axes.0 * inv_texel).length().max((fine_axes.1 * inv_texel).length()) >= FINE_TRACE_FROM
}

/// Most columns of its level a flyaway march crosses ([`grazing_level`]).
pub const GRAZING_COLUMNS: f32 = 1024.0;

/// The level a flyaway march of `level` reads along a path that crosses `columns`
/// level-0 column lines (|Δu| + |Δv| in texels across the tile plane): `level`, or the
/// coarser level whose columns it crosses at most [`GRAZING_COLUMNS`] of (clamped to
/// `last`). A ray near the horizon of a periodic sheet runs ~tan θ times the slab's depth
/// through the flyaway layer: at 89.99° over felt's 0.32-unit slab, some 34 000 level-0
/// columns, each of a grid's up to 48 rays. The felt 128² preset's flyaway layer is 27
/// texels deep: its marches keep level 0 to 88.5° (256 columns changed its 85° view by
/// 10%). Twin: `grazing_level` in shaders/common/level.glsl.
pub fn grazing_level(level: usize, columns: f32, last: usize) -> usize {
    if !(columns > GRAZING_COLUMNS) {
        return level;
    }
    // ∞ gives `last` (NaN does not reach here).
    let need = (columns / GRAZING_COLUMNS).log2().ceil();
    level.max(if need >= last as f32 { last } else { need as usize })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grazing_marches_read_the_level_whose_columns_they_cross_at_most_a_budget_of() {
        // Up to the budget: the level asked for.
        assert_eq!(grazing_level(0, 0.0, 7), 0);
        assert_eq!(grazing_level(2, GRAZING_COLUMNS, 7), 2);
        // Past it: the coarser level that brings the count within it, never finer.
        assert_eq!(grazing_level(0, GRAZING_COLUMNS + 1.0, 7), 1);
        assert_eq!(grazing_level(0, 4.0 * GRAZING_COLUMNS, 7), 2);
        assert_eq!(grazing_level(3, 4.0 * GRAZING_COLUMNS, 7), 3);
        for columns in [300.0f32, 1e4, 3.4e4] {
            let l = grazing_level(0, columns, 20);
            assert!(columns / (1u32 << l) as f32 <= GRAZING_COLUMNS && (l == 0 || columns / (1u32 << (l - 1)) as f32 > GRAZING_COLUMNS), "{columns}: {l}");
        }
        // Clamped to the coarsest level; ∞ clamps, NaN keeps the level.
        assert_eq!(grazing_level(0, 1e12, 5), 5);
        assert_eq!(grazing_level(1, f32::INFINITY, 5), 5);
        assert_eq!(grazing_level(1, f32::NAN, 5), 1);
    }
}
