//! Participating media: phase functions (the [`Phase`] interface, isotropic,
//! Henyey–Greenstein and Rayleigh) and homogeneous media with spectral coefficients.

pub mod medium;
pub mod phase;

pub use medium::{sample_free_flight, transmittance, FreeFlight, Medium, PhaseFunction};
pub use phase::{HenyeyGreenstein, Phase, PhaseSample, Rayleigh};
