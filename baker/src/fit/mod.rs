//! Fitting the spatially varying cloth BRDF (paper §5.3, Algorithm 1): training
//! configurations ([`directions`]), training renderings and the model-side samples
//! ([`samples`]), per-texel features ([`features`]), the lobes' energy bound ([`energy`]), clustering ([`kmeans`]), the
//! per-cluster fit ([`cluster_fit`], with its frame offset [`frames`]: Nelder–Mead over [`simplex`] with the linear
//! parameters by [`nnls`]), each texel's visibility gradient ([`gradient`]), the flyaways' fit ([`flyaways`]), the surface refitted behind them ([`behind`]) and, for a BSDF, the
//! transmission term's ([`transmission`]). The pipeline that
//! chains them is `crate::bake`.

pub mod behind;
pub mod cluster_fit;
pub mod directions;
pub mod energy;
pub mod features;
pub mod flyaways;
pub mod frames;
pub mod gradient;
pub mod kmeans;
pub mod nnls;
pub mod openness;
pub mod samples;
pub mod simplex;
pub mod transmission;
