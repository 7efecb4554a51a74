//! Closed forms the scene-level kinds share: what a furnace enclosure or white furnace must
//! read, Lambert's law under the scene's lights, emitted radiance along camera rays,
//! Beer–Lambert transmittance through absorbing media, and their averages over pixel
//! footprints, and the albedo of a white GGX conductor. Each is computed from the scene or
//! model description, not by rendering it or by furnace's model code.

pub mod emission;
pub mod footprint;
pub mod fresnel;
pub mod furnace;
pub mod ggx_albedo;
pub mod lambert;
pub mod refraction;
pub mod transmittance;
pub mod witness;
