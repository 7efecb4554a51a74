//! The models under test and how model-level kinds measure them: the catalogue of furnace's
//! BSDFs, phase functions and direction samplers, test directions, directional albedo, and
//! the shared phase-function test.

pub mod albedo;
pub mod catalogue;
pub mod directions;
pub mod phase;
