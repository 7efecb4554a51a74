//! Bottom layer: vectors, the local shading frame, warps with their pdfs, and the
//! counter-based random numbers that make renders independent of the thread count.
//!
//! All geometry is double precision (`glam::DVec3`); directions are unit vectors.

pub mod frame;
pub mod rng;
pub mod warp;

pub use glam::DVec3 as Vec3;

/// π as f64.
pub const PI: f64 = std::f64::consts::PI;
/// 1/π.
pub const INV_PI: f64 = std::f64::consts::FRAC_1_PI;

/// 64-bit FNV-1a hash (Fowler, Noll & Vo; the offset basis and prime of the 64-bit variant),
/// fed bytes or formatted text: a stable fingerprint, not a cryptographic one.
#[derive(Debug, Clone, Copy)]
pub struct Fnv1a(pub u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    /// Feeds `bytes`.
    pub fn eat(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
}

impl std::fmt::Write for Fnv1a {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.eat(s.as_bytes());
        Ok(())
    }
}
