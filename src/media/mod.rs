//! Participating media. For now: phase functions (the [`Phase`] interface and
//! Henyey–Greenstein); homogeneous media arrive with volumetric path tracing.

pub mod phase;

pub use phase::{HenyeyGreenstein, Phase, PhaseSample};
