//! Closed forms the scene-level kinds share: what a furnace enclosure or white furnace must
//! read, Lambert's law under the scene's lights, emitted radiance along camera rays, and their
//! averages over pixel footprints. Each is computed from the scene description, not by
//! rendering it.

pub mod emission;
pub mod footprint;
pub mod furnace;
pub mod lambert;
