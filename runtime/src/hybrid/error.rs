//! Why a hybrid model is invalid. Every variant says what and where (level, texel,
//! entry, node), so that a bad file or a bad bake can be traced.

/// Which array of BRDF headers an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableKind {
    /// A level's per-texel headers (per-texel encoding).
    SurfaceTexels,
    /// A level's cluster table (clustered encoding).
    SurfaceClusters,
    /// A level's flyaway parameter table.
    Flyaways,
}

impl std::fmt::Display for TableKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TableKind::SurfaceTexels => "surface texel BRDF",
            TableKind::SurfaceClusters => "surface cluster table",
            TableKind::Flyaways => "flyaway BRDF table",
        })
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    #[error("tile {field} = {value:?} is invalid ({why})")]
    Tile { field: &'static str, value: f32, why: &'static str },
    #[error("{what} is {width}x{height}; each side must be in 1..={max}")]
    Dims { what: &'static str, width: u32, height: u32, max: u32 },
    #[error("{count} levels; a {width}x{height} model has 1..={max}")]
    LevelCount { count: usize, width: u32, height: u32, max: usize },
    #[error("level {level} is {got_w}x{got_h}; expected {want_w}x{want_h} (level 0 halved {level} times, rounding up)")]
    LevelDims { level: usize, got_w: u32, got_h: u32, want_w: u32, want_h: u32 },
    #[error("{what} of level {level} has {got} entries; expected {expected}")]
    Length { what: &'static str, level: usize, expected: u64, got: u64 },
    #[error("height field has {got} samples; expected {expected}")]
    HeightLength { expected: u64, got: u64 },
    #[error("height field depth {value} at texel ({i}, {j}) is not in [0, height scale {scale}]")]
    Depth { i: u32, j: u32, value: f32, scale: f32 },
    #[error("{table} of level {level}, entry {entry}: {field} = {value} is out of range ({range})")]
    Param { table: TableKind, level: usize, entry: usize, field: &'static str, value: f32, range: &'static str },
    #[error("{table} of level {level}, entry {entry}: {count} lobes (allowed {min}..=8)")]
    LobeCount { table: TableKind, level: usize, entry: usize, count: u32, min: u32 },
    #[error("{table} of level {level}, entry {entry}: lobes {offset}..{offset}+{count} run past the {len} lobes stored")]
    LobeRange { table: TableKind, level: usize, entry: usize, offset: u32, count: u32, len: usize },
    #[error("{table} of level {level}, entry {entry}: reserved byte is {value}, must be 0")]
    Reserved { table: TableKind, level: usize, entry: usize, value: u8 },
    #[error("surface lobe {lobe} of level {level}: {field} = {value} is out of range ({range})")]
    LobeParam { level: usize, lobe: usize, field: &'static str, value: f32, range: &'static str },
    #[error("flyaway lobe {lobe} of level {level}: {field} = {value} is out of range ({range})")]
    FlyawayLobeParam { level: usize, lobe: usize, field: &'static str, value: f32, range: &'static str },
    #[error("transmission of texel {texel}, level {level}: {field} = {value} is out of range ({range})")]
    TransmissionParam { level: usize, texel: usize, field: &'static str, value: f32, range: &'static str },
    #[error("view tilt of texel {texel}, level {level}: {field} = {value}, must be finite with |value| <= {max}")]
    ViewTiltParam { level: usize, texel: usize, field: &'static str, value: f32, max: f32 },
    #[error("visibility gradient of texel {texel}, level {level}: {field} = {value}, must be finite with |value| <= {max}")]
    GradientParam { level: usize, texel: usize, field: &'static str, value: f32, max: f32 },
    #[error("transmission visibility of texel {texel}, level {level}: {field} = {value}, must be finite with |value| <= {max}")]
    TransmissionVisibilityParam { level: usize, texel: usize, field: &'static str, value: f32, max: f32 },
    #[error("level {level} has a transmission visibility but no transmission records")]
    TransmissionVisibilityAlone { level: usize },
    #[error("visibility curvature of texel {texel}, level {level}: {field} = {value}, must be finite with |value| <= {max}")]
    CurvatureParam { level: usize, texel: usize, field: &'static str, value: f32, max: f32 },
    #[error("level 0 has a view tilt section; only coarse levels may (level 0 is seen through its own height field)")]
    ViewTiltAtLevel0,
    #[error("texel ({i}, {j}) of level {level} uses cluster {index}, but the table has {len}")]
    ClusterIndex { level: usize, i: u32, j: u32, index: u32, len: usize },
    #[error("flyaway list of texel ({i}, {j}), level {level}: {link} points to node {index}, but there are {len}")]
    FlyawayLink { level: usize, i: u32, j: u32, link: &'static str, index: u32, len: usize },
    #[error("flyaway list of texel ({i}, {j}), level {level}: node {node} at depth {depth} follows depth {prev}; lists must go strictly down (this also rules out cycles)")]
    FlyawayOrder { level: usize, i: u32, j: u32, node: u32, depth: u16, prev: u16 },
    #[error("flyaway node {node} of level {level} is on more than one list (second time from texel ({i}, {j}))")]
    FlyawayShared { level: usize, node: u32, i: u32, j: u32 },
    #[error("flyaway node {node} of level {level} is on no list")]
    FlyawayUnreached { level: usize, node: u32 },
    #[error("flyaway node {node} of level {level}: {why}")]
    FlyawayNode { level: usize, node: u32, why: String },
    #[error("flyaway path gain of level {level}: {why}")]
    PathGain { level: usize, why: String },
    #[error("bake metadata: {0}")]
    Meta(String),
}
