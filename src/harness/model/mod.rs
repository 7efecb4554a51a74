//! The models under test and how model-level kinds measure them: the catalogue of furnace's
//! BSDFs, phase functions and lights, their in-process answers to the batched interface, the
//! model protocol's client and stand-in server, test directions, directional albedo, the
//! sampling routines the chi-square kind bins, the shared phase-function test, and how much of a
//! failed identity the model's own rounding explains.

pub mod albedo;
pub mod catalogue;
pub mod client;
pub mod conditioning;
pub mod controls;
pub mod directions;
pub mod local;
pub mod phase;
pub mod protocol;
pub mod samplers;
pub mod server;
