//! The check kinds, one file each: the kind's keys, its parameters, its closed form or
//! physical law with its source, and how it measures. Kinds do not use each other; what
//! several share lives in `closed_form/`, `model/`, `region.rs` or `compare.rs`.

pub mod albedo;
pub mod algorithm_agreement;
pub mod bdpt_strategies;
pub mod chi2;
pub mod convergence;
pub mod energy;
pub mod estimators;
pub mod furnace;
pub mod half_space;
pub mod hg;
pub mod image;
pub mod lambert;
pub mod measured;
pub mod phase;
pub mod radiance;
pub mod radiosity_furnace;
pub mod reciprocity;
pub mod reciprocity_image;
pub mod reference_convergence;
pub mod refraction;
pub mod scale;
pub mod smooth_limit;
pub mod transmittance;
pub mod weights;
