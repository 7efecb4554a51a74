//! Orthonormal frame around a normal: local coordinates have z along the normal, so
//! `cos θ = w.z` for a local direction `w`.

use super::Vec3;

/// An orthonormal basis (s, t, n); `to_local`/`to_world` map unit directions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent.
    pub t: Vec3,
    /// Normal (local z axis).
    pub n: Vec3,
}

impl Frame {
    /// Builds a frame from a unit normal without branches on the sign of `n.z`
    /// (Duff et al. 2017, "Building an Orthonormal Basis, Revisited", JCGT 6(1), Listing 3).
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// World direction to local coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local direction to world coordinates.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal_for_many_normals_including_poles() {
        let normals = [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(1e-12, 0.0, -1.0).normalize(),
            Vec3::new(0.3, -0.4, 0.5).normalize(),
        ];
        for n in normals {
            let f = Frame::from_normal(n);
            for (a, b) in [(f.s, f.t), (f.s, f.n), (f.t, f.n)] {
                assert!(a.dot(b).abs() < 1e-12);
            }
            for v in [f.s, f.t, f.n] {
                assert!((v.length() - 1.0).abs() < 1e-12);
            }
            let w = Vec3::new(0.2, 0.3, 0.9).normalize();
            assert!((f.to_world(f.to_local(w)) - w).length() < 1e-12);
        }
    }
}
