//! The hybrid fabric model (DESIGN.md §5–§6): what the baker writes, the GPU renderer
//! uploads and the CPU renderer ([`crate::cpu`]) draws.
//!
//! - [`model`]: the model in memory (tile geometry, height field, levels, metadata);
//! - [`lobe`]: packed BRDF records and tables (clustered or per-texel);
//! - [`flyaway`]: the flyaway volume as per-texel linked lists;
//! - [`packing`]: f16 / unorm16 / octahedral / tangent-angle packings and their errors;
//! - [`compact`]: the smaller file records of the coarse levels (format 1.7);
//! - [`format`]: the `.hyb` file (runtime/HYBRID_FORMAT.md), reader and writer;
//! - [`gpu_layout`]: the model as plain-data arrays for the GPU (std430), and a frame's parameters;
//! - [`stats`]: what `fabric inspect model.hyb` prints;
//! - [`examples`]: hand-built models with known answers, for tests.
//!
//! Storage per element (the paper's models are 25–41 MB for 1k² tiles):
//!
//! | element                        | bytes            |
//! |--------------------------------|------------------|
//! | height sample (level 0)        | 2                |
//! | clustered texel (n, t, cluster)| 8                |
//! | per-texel header               | 16 + 16 per lobe |
//! | cluster / flyaway table entry  | 16 + 16 per lobe |
//! | flyaway list head (per texel)  | 4                |
//! | flyaway node                   | 16               |
//! | compact per-texel header (1.7) | 8 + 12 per lobe  |
//! | view tilt (coarse levels)      | 12, compact 6    |
//!
//! A 1024² model with a clustered level 0 (10 B/texel with its height: 10 MiB) and
//! per-texel coarse levels (≈ 349 k texels, 16 + 16·L bytes each: 16.0 MiB at L = 2 lobes
//! on average, 37.3 MiB at L = 6) lands in the paper's range.

pub mod compact;
pub mod error;
pub mod examples;
pub mod flyaway;
pub mod format;
pub mod gpu_layout;
pub mod lobe;
pub mod model;
pub mod packing;
pub mod stats;

pub use error::{ModelError, TableKind};
pub use flyaway::{FlyawayNode, FlyawayInput, Flyaways, NO_NODE, PATH_GAIN_NODES, PackedAxisGroup, PackedAxisSpread, PathGain};
pub use lobe::{BrdfHeader, BrdfTable, ClusteredTexel, PackedCurvature, PackedGradient, PackedLobe, PackedTransmission, PackedTransmissionVisibility, PackedViewTilt, TexelBrdf, VIEW_TILT_MAX, decode_frame, encode_frame};
pub use model::{BakeMetadata, HeightField, HybridModel, Level, MAX_DIM, Surface, Tile, level_dims, max_levels};
pub use stats::{LevelStats, ModelStats, model_stats};
