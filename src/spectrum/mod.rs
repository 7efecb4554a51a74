//! Spectra: curves over wavelength (nm), the four hero wavelengths a path carries, the CIE
//! 1931 observer and the XYZ → linear sRGB conversion used for previews.
//!
//! Wavelengths are in nanometres over [`LAMBDA_MIN`, `LAMBDA_MAX`] = [360, 830] nm, the range
//! of the CIE 1931 tables. Radiance spectra are in W·sr⁻¹·m⁻²·nm⁻¹; reflectances are unitless.

pub mod cie;
pub mod color;
pub mod curve;
pub mod observer;
pub mod sampled;

pub use curve::{Outside, Spectrum};
pub use observer::Observer;
pub use sampled::{SampledSpectrum, Wavelengths, N_WAVELENGTHS};

/// Shortest wavelength rendered, nm.
pub const LAMBDA_MIN: f64 = 360.0;
/// Longest wavelength rendered, nm.
pub const LAMBDA_MAX: f64 = 830.0;
