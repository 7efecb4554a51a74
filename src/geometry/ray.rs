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
    let mut po = (sp.p + offset).to_array();
    for i in 0..3 {
        if off[i] > 0.0 {
            po[i] = po[i].next_up();
        } else if off[i] < 0.0 {
            po[i] = po[i].next_down();
        }
    }
    Vec3::from_array(po)
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
