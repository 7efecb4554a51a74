//! How much of a failed identity the model's own arithmetic explains: a value is re-queried at
//! the one-ulp neighbours of its input directions (in the model's precision), and the spread of
//! the answers is what rounding the inputs alone can change. An identity between two values is
//! excused when they differ by at most `SPREADS` times that spread plus the tolerance: an f32
//! model near grazing passes, a missing factor (an O(1) error where inputs are well-conditioned)
//! does not. Four, not one: a sampled direction is itself the output of a few roundings (reflect
//! or refract, then normalise), so it may sit a few ulps from the exact direction.

use crate::harness::under_test::Precision;
use crate::math::Vec3;

/// The six directions one representable value away from `w` in one component, in the
/// arithmetic of `precision` (not renormalised: the model sees them as they are).
pub fn ulp_neighbours(w: Vec3, precision: Precision) -> [Vec3; 6] {
    let a = w.to_array();
    let step = |x: f64, up: bool| match precision {
        Precision::F64 => {
            if up {
                x.next_up()
            } else {
                x.next_down()
            }
        }
        Precision::F32 => {
            let x = x as f32;
            (if up { x.next_up() } else { x.next_down() }) as f64
        }
    };
    std::array::from_fn(|k| {
        let mut b = a;
        b[k / 2] = step(b[k / 2], k % 2 == 0);
        Vec3::from_array(b)
    })
}

/// Largest |v − v0| over `values`, or NaN if any is not finite (which excuses nothing).
pub fn spread(v0: f64, values: impl IntoIterator<Item = f64>) -> f64 {
    let mut s = 0.0f64;
    for v in values {
        let d = (v - v0).abs();
        if !d.is_finite() {
            return f64::NAN;
        }
        s = s.max(d);
    }
    s
}

/// How many one-ulp spreads of rounding an identity may differ by.
pub const SPREADS: f64 = 4.0;

/// An identity's two sides differ by `err`; the inputs' rounding alone moves them by `spread`:
/// excused when err ≤ SPREADS·spread + tolerance.
pub fn excused(err: f64, spread: f64, tolerance: f64) -> bool {
    // an infinite error, or an infinite allowance, excuses nothing
    err.is_finite() && tolerance.is_finite() && err <= SPREADS * spread + tolerance
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_are_one_ulp_away_in_the_models_precision() {
        let w = Vec3::new(0.6, 0.0, 0.8);
        let n32 = ulp_neighbours(w, Precision::F32);
        assert_eq!(n32[0].x, (0.6f32).next_up() as f64);
        assert_eq!(n32[1].x, (0.6f32).next_down() as f64);
        assert_eq!(n32[2].y, f32::from_bits(1) as f64); // the smallest subnormal above 0
        let n64 = ulp_neighbours(w, Precision::F64);
        assert_eq!(n64[5].z, 0.8f64.next_down());
        assert_eq!(spread(1.0, [1.5, 0.75]), 0.5);
        assert!(spread(1.0, [f64::NAN, 2.0]).is_nan());
        assert!(!excused(0.1, spread(1.0, [f64::NAN]), 1.0));
        // an infinite error or allowance excuses nothing (an infinite weight was excused)
        assert!(!excused(f64::INFINITY, 0.0, f64::INFINITY));
        assert!(!excused(0.1, 0.0, f64::INFINITY));
        assert!(excused(0.1, 0.0, 0.2));
    }
}
