//! Triangle meshes: vertex positions in scene units, triangles by index, an area CDF for
//! uniform area sampling.

use super::{triangle, SurfacePoint};
use crate::math::{warp, Vec3};

/// A triangle mesh; the geometric normal of triangle (a, b, c) is normalize((b−a)×(c−a)),
/// reversed when `flip_normals`.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex indices per triangle (validated in range, non-degenerate).
    pub triangles: Vec<[u32; 3]>,
    /// Reverse every normal.
    pub flip_normals: bool,
    /// Running sum of triangle areas (last entry = total area).
    area_cdf: Vec<f64>,
    /// Vertices gathered per triangle, so intersection needs no index indirection.
    corners: Vec<[Vec3; 3]>,
    /// Each triangle's oriented unit normal, computed once (light sampling and every hit use it).
    normals: Vec<Vec3>,
    /// Every vertex on one plane (see [`TriangleMesh::is_planar`]).
    planar: bool,
}

impl TriangleMesh {
    /// Builds the mesh and its area table. Callers validate indices and areas first
    /// (see `scene`); an index out of range here is a programming error.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>, flip_normals: bool) -> Self {
        let corners = triangles
            .iter()
            .map(|t| t.map(|k| positions[k as usize]))
            .collect();
        let mut mesh = TriangleMesh {
            positions,
            triangles,
            flip_normals,
            area_cdf: Vec::new(),
            corners,
            normals: Vec::new(),
            planar: false,
        };
        mesh.normals = (0..mesh.triangles.len())
            .map(|i| mesh.computed_normal(i))
            .collect();
        mesh.planar = mesh.vertices_on_one_plane();
        let mut acc = 0.0;
        mesh.area_cdf = (0..mesh.triangles.len())
            .map(|i| {
                acc += mesh.triangle_area(i);
                acc
            })
            .collect();
        mesh
    }

    /// Vertices of triangle `i`.
    #[inline]
    pub fn vertices(&self, i: usize) -> [Vec3; 3] {
        self.corners[i]
    }

    /// Area of triangle `i`.
    pub fn triangle_area(&self, i: usize) -> f64 {
        let [a, b, c] = self.vertices(i);
        0.5 * (b - a).cross(c - a).length()
    }

    /// Total area.
    pub fn area(&self) -> f64 {
        self.area_cdf.last().copied().unwrap_or(0.0)
    }

    /// Unit geometric normal of triangle `i`.
    #[inline]
    pub fn normal(&self, i: usize) -> Vec3 {
        self.normals[i]
    }

    /// The normal from the corners: (v1 − v0) × (v2 − v0), normalised, flipped if asked.
    fn computed_normal(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.vertices(i);
        let n = (b - a).cross(c - a).normalize();
        if self.flip_normals {
            -n
        } else {
            n
        }
    }

    /// True when every vertex lies on the plane of the first triangle, to 1e-12 of the mesh's
    /// extent (the rounding of its coordinates). A segment ending on such a mesh from a point
    /// off its plane meets the plane only at that end, so the mesh cannot shadow it. The
    /// integrators also skip the mesh for a ray leaving it, whose origin moves off the plane
    /// by only a few ulps: a triangle raised by up to the tolerance could still catch such a
    /// ray, if it runs so close to the plane that it has climbed less than the tolerance when
    /// it reaches that triangle, and the skip treats that grazing ray as leaving the plane the
    /// mesh stands for.
    pub fn is_planar(&self) -> bool {
        self.planar
    }

    fn vertices_on_one_plane(&self) -> bool {
        let Some(&[p0, ..]) = self.corners.first() else {
            return false;
        };
        let n = self.normals[0];
        let (lo, hi) = self
            .positions
            .iter()
            .fold((p0, p0), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        let tolerance = 1e-12 * (hi - lo).length();
        self.corners
            .iter()
            .flatten()
            .all(|&p| n.dot(p - p0).abs() <= tolerance)
    }

    /// Bounds of triangle `i`.
    pub fn triangle_bounds(&self, i: usize) -> (Vec3, Vec3) {
        let [a, b, c] = self.vertices(i);
        (a.min(b).min(c), a.max(b).max(c))
    }

    /// Surface point at barycentrics `b` of triangle `i`.
    pub fn surface_point(&self, i: usize, b: [f64; 3]) -> SurfacePoint {
        triangle::surface_point(b, self.vertices(i), self.normal(i))
    }

    /// A point uniformly distributed over the whole mesh area (triangle chosen by area with
    /// `u_select`, position by the sqrt warp); pdf 1/area.
    pub fn sample(&self, u_select: f64, u: [f64; 2]) -> SurfacePoint {
        let target = u_select * self.area();
        let i = self
            .area_cdf
            .partition_point(|&c| c <= target)
            .min(self.triangles.len() - 1);
        let [b1, b2] = warp::uniform_triangle(u);
        self.surface_point(i, [1.0 - b1 - b2, b1, b2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad_mesh(lift: f64) -> TriangleMesh {
        let p = vec![
            Vec3::new(0.0, 5.0, 0.0),
            Vec3::new(1.0, 5.0, 0.0),
            Vec3::new(1.0, 5.0, 1.0),
            Vec3::new(0.0, 5.0 + lift, 1.0),
        ];
        TriangleMesh::new(p, vec![[0, 1, 2], [0, 2, 3]], false)
    }

    #[test]
    fn planar_only_when_every_vertex_is_on_one_plane() {
        assert!(quad_mesh(0.0).is_planar());
        // a fold far above coordinate rounding, and a ridge that could shadow itself
        assert!(!quad_mesh(1e-6).is_planar());
        assert!(!quad_mesh(0.5).is_planar());
        let corner = TriangleMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            vec![[0, 1, 2], [0, 2, 3]],
            false,
        );
        assert!(!corner.is_planar());
        assert!(!TriangleMesh::new(vec![], vec![], false).is_planar());
    }
}
