//! The flyaway volume of one level as per-texel linked lists of non-empty voxels above
//! the height field (paper §6; DESIGN.md §5–§6).
//!
//! Texel (i, j) of level ℓ owns the column of voxels over its footprint; voxel `depth` =
//! k of that column spans depths [k·s_ℓ, (k+1)·s_ℓ] below the tile's top plane, with
//! s_ℓ = `voxel_depth`·2^ℓ (the flyaway volume is downsampled in x, y and z alike).
//! `heads[j·w + i]` is the first node of the column's list, or [`NO_NODE`]; `next`
//! links the rest. Lists go strictly down (depth increasing), which is what a ray
//! marching down meets first, and rules out cycles by construction; every node is on
//! exactly one list. A node is 16 bytes: next, depth, alpha (the fraction of filled
//! children at coarse levels, 1 at level 0), the fiber axis ω_f (shading frame of
//! DESIGN.md §5: t = ω_f, n = ω_o made perpendicular to t) and an index into the
//! level's flyaway BRDF table. A coarse level may also give each node the spread of its
//! level-0 axes ([`PackedAxisSpread`], format 1.5; `brdf::axis_spread`).

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::error::{ModelError, TableKind};
use super::lobe::BrdfTable;
use super::packing::{octahedral_decode, octahedral_encode, unorm8, unorm16, unorm16_value};

/// End of a list.
pub const NO_NODE: u32 = u32::MAX;

/// One non-empty flyaway voxel. 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct FlyawayNode {
    /// Index of the next node of the same column, or [`NO_NODE`].
    pub next: u32,
    /// Voxel index below the top plane at this level: depths [k·s_ℓ, (k+1)·s_ℓ].
    pub depth: u16,
    /// Coverage α ∈ (0, 1], unorm16 (never 0: empty voxels are not stored).
    pub alpha: u16,
    /// Fiber axis ω_f, octahedral 2×snorm16 (sign irrelevant).
    pub tangent: [u16; 2],
    /// Index into the level's flyaway BRDF table.
    pub param: u32,
}

const _: () = assert!(core::mem::size_of::<FlyawayNode>() == 16);

impl FlyawayNode {
    pub fn alpha(&self) -> f32 {
        unorm16_value(self.alpha)
    }

    pub fn tangent(&self) -> Vec3 {
        octahedral_decode(self.tangent)
    }
}

/// The spread of a coarse node's fibres (`brdf::axis_spread`): the roll θ of its axis
/// tensor's second eigen-axis about the node's tangent, unorm16 over [0, π), the weights
/// λ₂, λ₃ of the second and third, unorm8 each (λ₂ + λ₃ ≤ 1), and the depth range of the
/// voxel its fibres occupy. 8 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedAxisSpread {
    pub roll: u16,
    pub lambda: [u8; 2],
    /// The depth range [z₀, z₁] of the voxel its fibres occupy, unorm8 fractions of its
    /// depth (z₀ ≤ z₁; the whole voxel: [0, 255]).
    pub slab: [u8; 2],
    pub reserved: u16,
}

const _: () = assert!(core::mem::size_of::<PackedAxisSpread>() == 8);

impl PackedAxisSpread {
    /// Packs roll θ (any angle; taken mod π) and weights λ₂, λ₃ (clamped to [0, 1],
    /// λ₃ lowered until the sum is ≤ 1 after rounding).
    pub fn new(roll: f32, lambda2: f32, lambda3: f32) -> PackedAxisSpread {
        let pi = std::f32::consts::PI;
        let theta = if roll.is_finite() { roll.rem_euclid(pi) } else { 0.0 };
        let code = ((theta / pi) * 65536.0).round().min(65535.0) as u16;
        let l2 = unorm8(lambda2);
        let l3 = unorm8(lambda3).min(255 - l2);
        PackedAxisSpread { roll: code, lambda: [l2, l3], slab: [0, 255], reserved: 0 }
    }

    /// The record with the occupied depth range [z0, z1] (fractions of the voxel's depth,
    /// rounded outward).
    pub fn with_slab(self, z0: f32, z1: f32) -> PackedAxisSpread {
        let lo = (z0.clamp(0.0, 1.0) * 255.0).floor() as u8;
        let hi = ((z1.clamp(0.0, 1.0) * 255.0).ceil() as u8).max(lo);
        PackedAxisSpread { slab: [lo, hi], ..self }
    }

    /// [z₀, z₁] as fractions of the voxel's depth.
    pub fn slab(&self) -> (f32, f32) {
        (self.slab[0] as f32 * (1.0 / 255.0), self.slab[1] as f32 * (1.0 / 255.0))
    }

    /// θ ∈ [0, π).
    pub fn roll(&self) -> f32 {
        self.roll as f32 * (std::f32::consts::PI / 65536.0)
    }

    /// λ₂, λ₃.
    pub fn lambdas(&self) -> (f32, f32) {
        (self.lambda[0] as f32 * (1.0 / 255.0), self.lambda[1] as f32 * (1.0 / 255.0))
    }

    /// The three axes of `node`'s record, with their weights.
    pub fn axes(&self, node: &FlyawayNode) -> crate::brdf::axis_spread::SpreadAxes {
        let (l2, l3) = self.lambdas();
        crate::brdf::axis_spread::spread_axes(node.tangent(), self.roll(), l2, l3)
    }
}

/// A coarse node's second group of fibre axes (format 1.8, the optional `FLYAWAY_GROUP`
/// section; `brdf::axis_spread::grouped_axes`): its axis, octahedral 2×snorm8, its share
/// of the node's fibres (unorm8; 0: the node is its record's one cone) and the spread
/// sin²δ of its circular cone (unorm8). The node's tangent and [`PackedAxisSpread`] are
/// then the first group's. 4 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedAxisGroup {
    pub axis: [u8; 2],
    pub share: u8,
    pub spread: u8,
}

const _: () = assert!(core::mem::size_of::<PackedAxisGroup>() == 4);

impl PackedAxisGroup {
    /// No second group.
    pub const NONE: PackedAxisGroup = PackedAxisGroup { axis: [0, 0], share: 0, spread: 0 };

    /// Packs axis `b` (need not be unit), share `w` and spread `s` (both clamped to [0, 1]).
    pub fn new(b: Vec3, share: f32, spread: f32) -> PackedAxisGroup {
        PackedAxisGroup { axis: super::packing::octahedral_encode8(b), share: unorm8(share), spread: unorm8(spread) }
    }

    pub fn axis(&self) -> Vec3 {
        super::packing::octahedral_decode8(self.axis)
    }

    pub fn share(&self) -> f32 {
        self.share as f32 * (1.0 / 255.0)
    }

    pub fn spread(&self) -> f32 {
        self.spread as f32 * (1.0 / 255.0)
    }

    /// A node's axes: `first` (its record's cone) and this group (`first` alone where
    /// the share is 0).
    pub fn axes(&self, first: crate::brdf::axis_spread::SpreadAxes) -> crate::brdf::axis_spread::SpreadAxes {
        use crate::brdf::axis_spread::{group_axes, grouped_axes};
        if self.share == 0 {
            return first;
        }
        grouped_axes(first, group_axes(self.axis(), self.spread()), self.share())
    }
}

/// A flyaway voxel as a baker or a test describes it (the builder's input).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyawayInput {
    /// Voxel index below the top plane at this level.
    pub depth: u16,
    /// Coverage in (0, 1].
    pub alpha: f32,
    /// Fiber direction (need not be unit).
    pub tangent: Vec3,
    /// Index into the level's flyaway BRDF table.
    pub param: u32,
}

/// Polar angles of the path gain's nodes: 0°, 10°, … 80° (format 1.9).
pub const PATH_GAIN_NODES: usize = 9;
/// Degrees between the path gain's nodes.
pub const PATH_GAIN_STEP_DEGREES: f32 = 10.0;
/// The range a stored gain must lie in (a reader refuses others).
pub const PATH_GAIN_RANGE: [f32; 2] = [0.25, 4.0];

/// A flyaway level's gain on its opacity exponent per polar angle θ of the ray (format
/// 1.9, the optional `FLYAWAY_PATH_GAIN` section; runtime/HYBRID_FORMAT.md §7.3): a node
/// crossed over a path ℓ has opacity 1 − (1 − α)^(g(θ)·ℓ/s), g linear in θ between the
/// nodes at 0°, 10°, … 80° and constant past 80°. Fitted so that a coarse level's mean
/// transmittance over the tile matches level 0's at each node's angle, and level 0's
/// the volume's (`baker/src/prefilter/path_gain.rs`): α says what a voxel hides seen
/// from above (or its density), and Beer's law from there is wrong at a slant by 5–20%
/// in the transmittance (baker/PREFILTER_MEASUREMENTS.md, "The coarse flyaways' opacity
/// by angle").
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PathGain(pub [f32; PATH_GAIN_NODES]);

impl PathGain {
    /// No gain: Beer's law from α (levels without the section).
    pub const ONE: PathGain = PathGain([1.0; PATH_GAIN_NODES]);

    /// The gain for a ray of direction `d` (unit): by its polar angle to the tile's
    /// normal, θ = acos |d.z|. Twin: `flyaway_path_gain` in shaders/common/flyaways.glsl.
    #[inline]
    pub fn at(&self, d: Vec3) -> f32 {
        let theta = d.z.abs().min(1.0).acos().to_degrees();
        let x = (theta / PATH_GAIN_STEP_DEGREES).clamp(0.0, (PATH_GAIN_NODES - 1) as f32);
        let k = (x as usize).min(PATH_GAIN_NODES - 2);
        let f = x - k as f32;
        self.0[k] + f * (self.0[k + 1] - self.0[k])
    }

    /// The first gain outside [`PATH_GAIN_RANGE`] (NaN included), with its node.
    pub fn invalid(&self) -> Option<(usize, f32)> {
        self.0.iter().copied().enumerate().find(|&(_, g)| !(PATH_GAIN_RANGE[0]..=PATH_GAIN_RANGE[1]).contains(&g))
    }
}

/// One level's flyaway lists and their BRDF table.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Flyaways {
    /// Per texel (x fastest): first node, or [`NO_NODE`].
    pub heads: Vec<u32>,
    pub nodes: Vec<FlyawayNode>,
    /// The BRDFs the nodes index (lobe frames unused: the fiber frame is used).
    pub table: BrdfTable,
    /// One record per node (in `nodes`' order) where the level stores its axes' spread
    /// (the optional `FLYAWAY_SPREAD` section); `None`: each node is one axis.
    pub spreads: Option<Vec<PackedAxisSpread>>,
    /// One second group of axes per node (in `nodes`' order; format 1.8, the optional
    /// `FLYAWAY_GROUP` section), only with `spreads`; `None`: one group per node.
    pub groups: Option<Vec<PackedAxisGroup>>,
    /// The gain on the opacity exponent by the ray's polar angle (format 1.9, the
    /// optional `FLYAWAY_PATH_GAIN` section); `None`: 1 at every angle.
    pub path_gain: Option<PathGain>,
}

impl FlyawayInput {
    /// The level-0 depth index of source voxel layer `z` (0 at the bottom face) of a
    /// volume `zres` voxels thick: layers are counted down from the top plane.
    pub fn depth_of_voxel_layer(z: u32, zres: u32) -> Option<u16> {
        zres.checked_sub(z + 1).and_then(|k| u16::try_from(k).ok())
    }
}

impl Flyaways {
    /// Builds the lists of a `width`×`height` level from each column's voxels (in any
    /// order; they are sorted by depth). Nodes are stored column by column, top down, so
    /// a list is contiguous in memory. Errors: two voxels at one depth, α outside (0, 1].
    pub fn from_columns(width: u32, height: u32, table: BrdfTable, mut column: impl FnMut(u32, u32) -> Vec<FlyawayInput>) -> Result<Flyaways, ModelError> {
        let mut heads = Vec::with_capacity(width as usize * height as usize);
        let mut nodes: Vec<FlyawayNode> = Vec::new();
        for j in 0..height {
            for i in 0..width {
                let mut voxels = column(i, j);
                voxels.sort_by_key(|v| v.depth);
                heads.push(if voxels.is_empty() { NO_NODE } else { nodes.len() as u32 });
                for (k, v) in voxels.iter().enumerate() {
                    let node = nodes.len() as u32;
                    if k > 0 && voxels[k - 1].depth == v.depth {
                        return Err(ModelError::FlyawayOrder { level: 0, i, j, node, depth: v.depth, prev: v.depth });
                    }
                    if !(v.alpha > 0.0 && v.alpha <= 1.0) || unorm16(v.alpha) == 0 {
                        return Err(ModelError::FlyawayNode { level: 0, node, why: format!("alpha {} is not in (0, 1]", v.alpha) });
                    }
                    let next = if k + 1 < voxels.len() { node + 1 } else { NO_NODE };
                    nodes.push(FlyawayNode { next, depth: v.depth, alpha: unorm16(v.alpha), tangent: octahedral_encode(v.tangent), param: v.param });
                }
            }
        }
        Ok(Flyaways { heads, nodes, table, spreads: None, groups: None, path_gain: None })
    }

    /// The list of texel `index` (= j·width + i), top down. Stops after `nodes.len()`
    /// steps even on an unvalidated cyclic list.
    pub fn list(&self, index: usize) -> FlyawayList<'_> {
        FlyawayList { nodes: &self.nodes, current: self.heads.get(index).copied().unwrap_or(NO_NODE), remaining: self.nodes.len() }
    }

    /// Checks the lists of a `width`×`height` level ℓ = `level`: links in range, depths
    /// strictly increasing along each list and below `depth_limit`, each node on exactly
    /// one list, α > 0, parameter indices in range, and the table itself. O(nodes).
    pub fn validate(&self, level: usize, width: u32, height: u32, depth_limit: u32) -> Result<(), ModelError> {
        let texels = width as u64 * height as u64;
        if self.heads.len() as u64 != texels {
            return Err(ModelError::Length { what: "flyaway list heads", level, expected: texels, got: self.heads.len() as u64 });
        }
        if self.nodes.len() >= NO_NODE as usize {
            return Err(ModelError::Length { what: "flyaway nodes", level, expected: NO_NODE as u64 - 1, got: self.nodes.len() as u64 });
        }
        self.table.validate(TableKind::Flyaways, level, 0)?;
        let len = self.nodes.len();
        let mut seen = vec![false; len];
        for (index, &head) in self.heads.iter().enumerate() {
            let (i, j) = ((index % width as usize) as u32, (index / width as usize) as u32);
            let mut link = ("head", head);
            let mut prev: Option<u16> = None;
            while link.1 != NO_NODE {
                let node = link.1;
                let n = self.nodes.get(node as usize).ok_or(ModelError::FlyawayLink { level, i, j, link: link.0, index: node, len })?;
                if let Some(p) = prev.filter(|&p| n.depth <= p) {
                    return Err(ModelError::FlyawayOrder { level, i, j, node, depth: n.depth, prev: p });
                }
                // Strictly increasing depths bound a list's length by 65536 and rule out
                // cycles; `seen` rules out lists sharing a tail.
                if std::mem::replace(&mut seen[node as usize], true) {
                    return Err(ModelError::FlyawayShared { level, node, i, j });
                }
                if n.alpha == 0 {
                    return Err(ModelError::FlyawayNode { level, node, why: "alpha is 0 (empty voxels are not stored)".into() });
                }
                if n.depth as u32 >= depth_limit {
                    return Err(ModelError::FlyawayNode { level, node, why: format!("depth index {} is below the height field's slab ({} voxels deep at this level)", n.depth, depth_limit) });
                }
                if n.param as usize >= self.table.headers.len() {
                    return Err(ModelError::FlyawayNode { level, node, why: format!("BRDF index {} past the table's {} entries", n.param, self.table.headers.len()) });
                }
                prev = Some(n.depth);
                link = ("next", n.next);
            }
        }
        if let Some(node) = seen.iter().position(|s| !s) {
            return Err(ModelError::FlyawayUnreached { level, node: node as u32 });
        }
        if let Some((node, g)) = self.path_gain.as_ref().and_then(PathGain::invalid) {
            return Err(ModelError::PathGain { level, why: format!("{g} at {}° is outside [{}, {}]", node as f32 * PATH_GAIN_STEP_DEGREES, PATH_GAIN_RANGE[0], PATH_GAIN_RANGE[1]) });
        }
        if self.groups.is_some() && self.spreads.is_none() {
            // The second group is the rest of a node whose record gives the first.
            return Err(ModelError::Length { what: "flyaway spread records (axis groups need them)", level, expected: len as u64, got: 0 });
        }
        if let Some(spreads) = &self.spreads {
            if spreads.len() != len {
                return Err(ModelError::Length { what: "flyaway spread records", level, expected: len as u64, got: spreads.len() as u64 });
            }
            if let Some(node) = spreads.iter().position(|s| s.lambda[0] as u32 + s.lambda[1] as u32 > 255) {
                let s = spreads[node];
                return Err(ModelError::FlyawayNode { level, node: node as u32, why: format!("spread weights λ₂ = {}/255 and λ₃ = {}/255 sum past 1", s.lambda[0], s.lambda[1]) });
            }
            if let Some(node) = spreads.iter().position(|s| s.slab[0] > s.slab[1]) {
                let s = spreads[node];
                return Err(ModelError::FlyawayNode { level, node: node as u32, why: format!("occupied depth range [{}, {}]/255 is reversed", s.slab[0], s.slab[1]) });
            }
            if let Some(groups) = &self.groups {
                if groups.len() != len {
                    return Err(ModelError::Length { what: "flyaway axis groups", level, expected: len as u64, got: groups.len() as u64 });
                }
            }
            if let Some(node) = spreads.iter().position(|s| s.reserved != 0) {
                return Err(ModelError::FlyawayNode { level, node: node as u32, why: format!("reserved spread field is {}, not 0", spreads[node].reserved) });
            }
        }
        Ok(())
    }

    /// Bytes these lists take in the file (heads, nodes, spread records, axis groups, table).
    pub fn byte_size(&self) -> u64 {
        let groups = self.groups.as_ref().map_or(0, |g| g.len() * size_of::<PackedAxisGroup>()) as u64;
        let spreads = self.spreads.as_ref().map_or(0, |s| s.len() * if super::compact::compact_spreads(s).is_some() { size_of::<super::compact::CompactAxisSpread>() } else { size_of::<PackedAxisSpread>() });
        let node = if super::compact::compact_flyaway_nodes(self).is_some() { size_of::<super::compact::CompactFlyawayNode>() } else { size_of::<FlyawayNode>() };
        let gain = self.path_gain.map_or(0, |_| size_of::<PathGain>()) as u64;
        (self.heads.len() * 4 + self.nodes.len() * node + spreads) as u64 + groups + gain + self.table.byte_size()
    }

    /// The node at `index` and its axes (one axis, weight 1, where the level has no
    /// spread records; its two groups where it has a second, format 1.8).
    pub fn node_axes(&self, index: usize) -> crate::brdf::axis_spread::SpreadAxes {
        let node = &self.nodes[index];
        let first = match self.spreads.as_ref().and_then(|s| s.get(index)) {
            Some(s) => s.axes(node),
            None => return crate::brdf::axis_spread::SpreadAxes::single(node.tangent()),
        };
        match self.groups.as_ref().and_then(|g| g.get(index)) {
            Some(g) => g.axes(first),
            None => first,
        }
    }
}

/// The nodes of one list, top down.
pub struct FlyawayList<'a> {
    nodes: &'a [FlyawayNode],
    current: u32,
    remaining: usize,
}

impl<'a> FlyawayList<'a> {
    /// The same nodes with their indices in the level's `nodes`.
    pub fn with_index(mut self) -> impl Iterator<Item = (usize, &'a FlyawayNode)> {
        std::iter::from_fn(move || {
            let index = self.current as usize;
            self.next().map(|n| (index, n))
        })
    }
}

impl<'a> Iterator for FlyawayList<'a> {
    type Item = &'a FlyawayNode;

    fn next(&mut self) -> Option<&'a FlyawayNode> {
        if self.remaining == 0 {
            return None;
        }
        let node = self.nodes.get(self.current as usize)?;
        self.remaining -= 1;
        self.current = node.next;
        Some(node)
    }
}

#[cfg(test)]
mod tests {
    use crate::hybrid::{PATH_GAIN_NODES, PathGain};

    #[test]
    fn the_path_gain_is_linear_in_the_polar_angle_and_constant_past_80() {
        let g = PathGain(std::array::from_fn::<f32, PATH_GAIN_NODES, _>(|k| 1.0 + 0.1 * k as f32 + 0.02 * (k * k) as f32));
        let at = |theta: f32, down: bool| g.at(crate::scene::direction_from_angles(theta, 37.0) * if down { -1.0 } else { 1.0 });
        for k in 0..PATH_GAIN_NODES {
            let theta = 10.0 * k as f32;
            assert!((at(theta, true) - g.0[k]).abs() < 1e-4, "node {k}: {} vs {}", at(theta, true), g.0[k]);
            // The sign of d.z does not matter.
            assert!((at(theta, false) - at(theta, true)).abs() < 1e-6);
        }
        // Halfway between nodes 3 and 4 (35°), and past the last node.
        assert!((at(35.0, true) - 0.5 * (g.0[3] + g.0[4])).abs() < 1e-4);
        assert!((at(86.0, true) - g.0[8]).abs() < 1e-6 && (at(90.0, true) - g.0[8]).abs() < 1e-6);
        assert_eq!(PathGain::ONE.at(glam::Vec3::new(0.3, 0.4, -0.5).normalize()), 1.0);
        // The stored range: NaN and the ends' outsides are refused.
        assert_eq!(g.invalid(), None);
        for (bad, node) in [(f32::NAN, 2), (0.2, 0), (4.5, 8)] {
            let mut b = g;
            b.0[node] = bad;
            assert_eq!(b.invalid().map(|(k, _)| k), Some(node));
        }
    }

    use super::*;
    use crate::brdf::{ClothLobe, ClothParams};

    fn table() -> BrdfTable {
        let mut t = BrdfTable::new();
        t.push(&ClothParams::new(Vec3::splat(0.1), 1.5, 0.0, &[ClothLobe { k: Vec3::ONE, beta: 0.2, gamma: 0.0 }]));
        t
    }

    fn voxel(depth: u16) -> FlyawayInput {
        FlyawayInput { depth, alpha: 1.0, tangent: Vec3::X, param: 0 }
    }

    #[test]
    fn builder_sorts_columns_and_validation_accepts_them() {
        let f = Flyaways::from_columns(3, 2, table(), |i, j| if (i + j) % 2 == 0 { vec![voxel(5), voxel(2), voxel(9)] } else { vec![] }).unwrap();
        f.validate(0, 3, 2, 10).unwrap();
        let depths: Vec<u16> = f.list(0).map(|n| n.depth).collect();
        assert_eq!(depths, [2, 5, 9]);
        assert_eq!(f.list(1).count(), 0);
        assert_eq!(f.nodes.len(), 9);
        assert!(matches!(f.validate(0, 3, 2, 9), Err(ModelError::FlyawayNode { .. })), "depth 9 is outside a 9-voxel slab");
    }

    #[test]
    fn cycles_shared_tails_and_strays_are_rejected() {
        let mut f = Flyaways::from_columns(2, 1, table(), |i, _| if i == 0 { vec![voxel(1), voxel(2)] } else { vec![voxel(3)] }).unwrap();
        f.validate(0, 2, 1, 10).unwrap();
        let good = f.clone();
        // Cycle: the second node points back at the first.
        f.nodes[1].next = 0;
        assert!(matches!(f.validate(0, 2, 1, 10), Err(ModelError::FlyawayOrder { node: 0, .. })));
        assert_eq!(f.list(0).count(), 3, "iteration stops even on a cycle");
        // Shared tail: column 1 starts inside column 0's list.
        let mut f = good.clone();
        f.heads[1] = 1;
        assert!(matches!(f.validate(0, 2, 1, 10), Err(ModelError::FlyawayShared { node: 1, .. })));
        // Dangling link.
        let mut f = good.clone();
        f.nodes[0].next = 77;
        assert!(matches!(f.validate(0, 2, 1, 10), Err(ModelError::FlyawayLink { index: 77, .. })));
        // A node on no list.
        let mut f = good.clone();
        f.heads[1] = NO_NODE;
        assert!(matches!(f.validate(0, 2, 1, 10), Err(ModelError::FlyawayUnreached { node: 2, .. })));
        // Bad parameter index and zero alpha.
        let mut f = good.clone();
        f.nodes[2].param = 1;
        assert!(matches!(f.validate(0, 2, 1, 10), Err(ModelError::FlyawayNode { node: 2, .. })));
        let mut f = good;
        f.nodes[0].alpha = 0;
        assert!(matches!(f.validate(0, 2, 1, 10), Err(ModelError::FlyawayNode { node: 0, .. })));
    }

    #[test]
    fn builder_rejects_duplicates_and_bad_alpha() {
        assert!(Flyaways::from_columns(1, 1, table(), |_, _| vec![voxel(1), voxel(1)]).is_err());
        assert!(Flyaways::from_columns(1, 1, table(), |_, _| vec![FlyawayInput { alpha: 0.0, ..voxel(1) }]).is_err());
        assert!(Flyaways::from_columns(1, 1, table(), |_, _| vec![FlyawayInput { alpha: f32::NAN, ..voxel(1) }]).is_err());
    }
}
