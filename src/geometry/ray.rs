//! Rays and the one ray-spawning policy: offset the origin along the normal by the point's
//! error bound (PBR 3rd ed., §3.9.5 "Robust spawned ray origins").

use super::SurfacePoint;
use crate::math::Vec3;

/// A ray with origin `o` and unit direction `d` (scene units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Unit direction.
    pub d: Vec3,
}

impl Ray {
    /// Point at distance `t`.
    #[inline]
    pub fn at(&self, t: f64) -> Vec3 {
        self.o + self.d * t
    }
}

/// The origin for a ray leaving `sp` in direction `w`: moved along ±n just past the error
/// box, then each component rounded one ulp away from `sp.p` (PBR 3rd ed., §3.9.5). Inlined,
/// so that a direction just computed reaches the side test in registers rather than through
/// memory (docs/performance.md, "Spawned origins take the side, not the direction").
#[inline(always)]
pub fn offset_origin(sp: &SurfacePoint, w: Vec3) -> Vec3 {
    offset_to_side(sp, w.dot(sp.n) < 0.0)
}

/// [`offset_origin`] to the side of `sp`'s normal (`below`: against it).
#[inline]
fn offset_to_side(sp: &SurfacePoint, below: bool) -> Vec3 {
    let d = sp.n.abs().dot(sp.p_error);
    let mut offset = sp.n * d;
    if below {
        offset = -offset;
    }
    // plain arrays: constant-size indexing without Vec3's checked Index/IndexMut
    let off = offset.to_array();
    let po = (sp.p + offset).to_array();
    if !po.iter().all(|&x| nonzero_finite(x)) {
        return Vec3::from_array(std::array::from_fn(|i| ulp_towards_slow(po[i], off[i])));
    }
    Vec3::from_array(std::array::from_fn(|i| ulp_towards(po[i], off[i])))
}

/// Whether `x` is neither zero nor infinite nor NaN, without a branch: the bits of |x| minus
/// one wrap for zero and reach infinity's minus one for the rest.
#[inline(always)]
fn nonzero_finite(x: f64) -> bool {
    (x.to_bits() & !(1 << 63)).wrapping_sub(1) < f64::INFINITY.to_bits() - 1
}

/// A nonzero finite `x` moved one ulp up where `dir` > 0 and one down where `dir` < 0
/// (`next_up`, `next_down`), unchanged where `dir` is 0 or NaN: its bit pattern steps by ±1
/// without a branch on either sign (the signs of spawned origins are data, so the branches of
/// `next_up` mispredict).
#[inline(always)]
fn ulp_towards(x: f64, dir: f64) -> f64 {
    // the magnitude grows (bits + 1) when x and dir share a sign, shrinks (bits − 1) otherwise
    let step = i64::from(dir > 0.0) - i64::from(dir < 0.0);
    let sign = 1 - 2 * (x.to_bits() >> 63) as i64;
    f64::from_bits(x.to_bits().wrapping_add_signed(step * sign))
}

/// [`ulp_towards`] for any `x`, through `next_up` and `next_down`.
fn ulp_towards_slow(x: f64, dir: f64) -> f64 {
    if dir > 0.0 {
        x.next_up()
    } else if dir < 0.0 {
        x.next_down()
    } else {
        x
    }
}

/// A ray leaving `sp` in unit direction `w`.
#[inline(always)]
pub fn spawn(sp: &SurfacePoint, w: Vec3) -> Ray {
    Ray {
        o: offset_origin(sp, w),
        d: w,
    }
}

/// A shadow ray from `from` towards `to`, with both ends moved off their surfaces.
/// Returns the ray and the distance at which it must stop (exclusive).
pub fn spawn_to(from: &SurfacePoint, to: &SurfacePoint) -> (Ray, f64) {
    let w = to.p - from.p;
    let o = offset_origin(from, w);
    let target = offset_origin(to, -w);
    let v = target - o;
    let dist = v.length();
    // 1e-9 relative: far above f64 rounding of t, far below any geometric feature.
    (Ray { o, d: v / dist }, dist * (1.0 - 1e-9))
}

#[cfg(test)]
mod tests {
    use super::{nonzero_finite, ulp_towards, ulp_towards_slow};

    #[test]
    fn the_ulp_steps_are_next_up_and_next_down_bit_for_bit() {
        let mut xs = vec![
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            f64::from_bits(1),
            -f64::from_bits(1),
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1.0,
            -1.0,
            0.3,
            -2.5e-300,
        ];
        // a spread of magnitudes and signs
        let mut z = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..10_000 {
            z = z
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            xs.push(f64::from_bits(z));
        }
        for &x in &xs {
            for dir in [1.0, -1.0, 0.0, -0.0, 1e-300, -1e300, f64::NAN] {
                let want = if dir > 0.0 {
                    x.next_up()
                } else if dir < 0.0 {
                    x.next_down()
                } else {
                    x
                };
                let plain = nonzero_finite(x);
                assert_eq!(plain, x != 0.0 && x.is_finite());
                let got = if plain {
                    ulp_towards(x, dir)
                } else {
                    ulp_towards_slow(x, dir)
                };
                assert!(
                    got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                    "x {x:e} ({:#x}), dir {dir}: {got:e} against {want:e}",
                    x.to_bits()
                );
            }
        }
    }
}
