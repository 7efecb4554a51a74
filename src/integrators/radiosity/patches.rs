//! Patches: each quad cut into an nu × nv grid of parallelograms and each triangle into m²
//! similar triangles (midpoint subdivision), with edges no longer than the patch size; and
//! the way back from a surface point to its patch.

use crate::geometry::Shape;
use crate::math::Vec3;

/// One planar patch: a parallelogram or a triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct Patch {
    /// Vertices in order (3 or 4; for a triangle the fourth repeats the third).
    pub vertices: [Vec3; 4],
    /// 3 or 4.
    pub n_vertices: usize,
    /// Unit normal (the shape's, after flip_normals).
    pub normal: Vec3,
    /// Area, scene units².
    pub area: f64,
    /// Index of the shape it belongs to.
    pub shape: u32,
}

impl Patch {
    /// The polygon's vertices.
    pub fn polygon(&self) -> &[Vec3] {
        &self.vertices[..self.n_vertices]
    }

    /// The centres of the patch's 2×2 equal-area sub-patches: the quadrature points of the
    /// form factors (midpoint rule on each quarter; for a triangle, the centroids of its four
    /// midpoint sub-triangles).
    pub fn quadrature(&self) -> [Vec3; 4] {
        let v = self.vertices;
        if self.n_vertices == 4 {
            let (c, u, w) = (v[0], v[1] - v[0], v[3] - v[0]);
            [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)].map(|(a, b)| c + u * a + w * b)
        } else {
            let (a, b, c) = (v[0], v[1], v[2]);
            let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
            let centroid = |p: Vec3, q: Vec3, r: Vec3| (p + q + r) / 3.0;
            [
                centroid(a, ab, ca),
                centroid(ab, b, bc),
                centroid(ca, bc, c),
                centroid(ab, bc, ca),
            ]
        }
    }
}

/// How one shape was cut, to find the patch of a surface point.
#[derive(Debug, Clone, PartialEq)]
pub enum Cut {
    /// A quad: corner, the dual basis of its edges (p − corner = a·edge_u + b·edge_v with
    /// a = (p − corner)·du, b = (p − corner)·dv), its grid, and its first patch.
    Quad {
        /// The quad's corner.
        corner: Vec3,
        /// Dual of edge_u.
        du: Vec3,
        /// Dual of edge_v.
        dv: Vec3,
        /// Cells along edge_u and edge_v.
        grid: [usize; 2],
        /// Index of cell (0, 0).
        first: usize,
    },
    /// A triangle mesh: per triangle its corners and first patch, each cut m × m.
    Mesh {
        /// Per triangle: corners, subdivision m, index of its first patch.
        triangles: Vec<([Vec3; 3], usize, usize)>,
    },
}

/// Why the scene cannot be meshed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A shape radiosity does not mesh.
    #[error("radiosity meshes quads and triangle meshes; shape {0} is an analytic sphere (tessellate it into a triangle mesh)")]
    Sphere(usize),
    /// Too many patches for the dense O(n²) form-factor matrix.
    #[error("patch size {size:?} gives {count} patches, more than the {limit} a dense radiosity solve allows (its form factors cost n² in time and memory); use a patch size of at least {suggested:.3e}")]
    TooMany {
        /// Requested patch size, scene units.
        size: f64,
        /// Patches it would give.
        count: u64,
        /// The limit.
        limit: u64,
        /// A patch size that fits.
        suggested: f64,
    },
    /// More triangles and quads than patches allowed: no patch size fits.
    #[error("the scene has {count} quads and triangles, more than the {limit} patches a dense radiosity solve allows at any patch size")]
    TooManyPrimitives {
        /// Quads and triangles.
        count: u64,
        /// The limit.
        limit: u64,
    },
}

/// Patches the solver accepts at most (up to n form factors of 16 bytes in each of 2n rows,
/// 537 MB at 4096).
pub const MAX_PATCHES: u64 = 4096;

fn cells(edge: f64, size: f64) -> usize {
    ((edge / size).ceil() as usize).max(1)
}

/// Patches a shape list gives at `size` (checked before any are built).
pub fn count(shapes: &[Shape], size: f64) -> Result<u64, MeshError> {
    let mut n: u64 = 0;
    for (i, s) in shapes.iter().enumerate() {
        n = n.saturating_add(match s {
            Shape::Sphere(_) => return Err(MeshError::Sphere(i)),
            Shape::Quad(q) => {
                (cells(q.edge_u.length(), size) as u64)
                    .saturating_mul(cells(q.edge_v.length(), size) as u64)
            }
            Shape::Mesh(m) => (0..m.triangles.len())
                .map(|t| {
                    let k = triangle_cuts(&m.vertices(t), size) as u64;
                    k.saturating_mul(k)
                })
                .fold(0u64, u64::saturating_add),
        });
    }
    Ok(n)
}

fn triangle_cuts(v: &[Vec3; 3], size: f64) -> usize {
    let longest = (v[1] - v[0])
        .length()
        .max((v[2] - v[1]).length())
        .max((v[0] - v[2]).length());
    cells(longest, size)
}

/// Cuts every shape into patches of edge at most `size` (scene units).
pub fn mesh(shapes: &[Shape], size: f64) -> Result<(Vec<Patch>, Vec<Cut>), MeshError> {
    let total = count(shapes, size)?;
    let primitives: u64 = shapes.iter().map(|s| s.primitive_count() as u64).sum();
    if primitives > MAX_PATCHES {
        return Err(MeshError::TooManyPrimitives {
            count: primitives,
            limit: MAX_PATCHES,
        });
    }
    if total > MAX_PATCHES {
        // patch count scales as 1/size², so this size gives about MAX_PATCHES
        let suggested = size * (total as f64 / MAX_PATCHES as f64).sqrt() * 1.01;
        return Err(MeshError::TooMany {
            size,
            count: total,
            limit: MAX_PATCHES,
            suggested,
        });
    }
    let mut patches = Vec::with_capacity(total as usize);
    let mut cuts = Vec::with_capacity(shapes.len());
    for (i, s) in shapes.iter().enumerate() {
        let shape = i as u32;
        match s {
            Shape::Sphere(_) => return Err(MeshError::Sphere(i)),
            Shape::Quad(q) => {
                let grid = [
                    cells(q.edge_u.length(), size),
                    cells(q.edge_v.length(), size),
                ];
                let (u, v) = (q.edge_u / grid[0] as f64, q.edge_v / grid[1] as f64);
                let normal = q.normal();
                let first = patches.len();
                for j in 0..grid[1] {
                    for k in 0..grid[0] {
                        let c = q.corner
                            + q.edge_u * (k as f64 / grid[0] as f64)
                            + q.edge_v * (j as f64 / grid[1] as f64);
                        patches.push(Patch {
                            vertices: [c, c + u, c + u + v, c + v],
                            n_vertices: 4,
                            normal,
                            area: u.cross(v).length(),
                            shape,
                        });
                    }
                }
                // dual basis: du·edge_u = 1, du·edge_v = 0 (and the reverse for dv)
                let cr = q.edge_u.cross(q.edge_v);
                let inv = 1.0 / cr.length_squared();
                cuts.push(Cut::Quad {
                    corner: q.corner,
                    du: q.edge_v.cross(cr) * inv,
                    dv: cr.cross(q.edge_u) * inv,
                    grid,
                    first,
                });
            }
            Shape::Mesh(m) => {
                let mut triangles = Vec::with_capacity(m.triangles.len());
                for t in 0..m.triangles.len() {
                    let v = m.vertices(t);
                    let k = triangle_cuts(&v, size);
                    let normal = m.normal(t);
                    triangles.push((v, k, patches.len()));
                    let (e1, e2) = ((v[1] - v[0]) / k as f64, (v[2] - v[0]) / k as f64);
                    let area = 0.5 * e1.cross(e2).length();
                    let at = |i: usize, j: usize| v[0] + e1 * i as f64 + e2 * j as f64;
                    for (i, j, upper) in sub_triangles(k) {
                        let vertices = if upper {
                            [at(i + 1, j), at(i + 1, j + 1), at(i, j + 1), at(i, j + 1)]
                        } else {
                            [at(i, j), at(i + 1, j), at(i, j + 1), at(i, j + 1)]
                        };
                        patches.push(Patch {
                            vertices,
                            n_vertices: 3,
                            normal,
                            area,
                            shape,
                        });
                    }
                }
                cuts.push(Cut::Mesh { triangles });
            }
        }
    }
    Ok((patches, cuts))
}

/// The m² sub-triangles of a triangle cut m times along each edge, in the order
/// [`patch_of`] indexes them: cell (i, j) with i + j < m has a lower triangle, and an upper
/// one when i + j < m − 1.
fn sub_triangles(m: usize) -> impl Iterator<Item = (usize, usize, bool)> {
    (0..m).flat_map(move |j| {
        (0..m - j).flat_map(move |i| {
            let upper = i + j + 1 < m;
            std::iter::once((i, j, false)).chain(upper.then_some((i, j, true)))
        })
    })
}

/// Index within a triangle's patches of cell (i, j), lower or upper, for cut m.
fn sub_index(m: usize, i: usize, j: usize, upper: bool) -> usize {
    // rows before j hold Σ_{r<j} (2(m − r) − 1) = j(2m − j) patches
    let before = j * (2 * m - j);
    before + 2 * i + usize::from(upper)
}

/// The patch holding surface point `p` of shape `shape` (clamped to the shape's cells; for a
/// mesh, the triangle whose barycentric coordinates of `p` are least negative).
pub fn patch_of(cut: &Cut, p: Vec3) -> usize {
    match cut {
        Cut::Quad {
            corner,
            du,
            dv,
            grid,
            first,
        } => {
            let d = p - *corner;
            let cell = |t: f64, n: usize| ((t * n as f64).floor().max(0.0) as usize).min(n - 1);
            first + cell(d.dot(*dv), grid[1]) * grid[0] + cell(d.dot(*du), grid[0])
        }
        Cut::Mesh { triangles } => {
            // the triangle p lies on: nearest plane first (a point on one face of a box
            // projects inside the opposite face too), then the least negative barycentric
            let score = |(v, _, _): &([Vec3; 3], usize, usize)| {
                let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
                let (b1, b2) = barycentric(v, p);
                let scale = (v[1] - v[0]).length() + (v[2] - v[0]).length();
                // distance to the plane in units of 1e-9 of the triangle's size: rounding ties
                let dist = (n.dot(p - v[0]).abs() / (scale * 1e-9)).round();
                (dist, -b1.min(b2).min(1.0 - b1 - b2))
            };
            let Some((v, m, first)) = triangles.iter().min_by(|a, b| {
                score(a)
                    .partial_cmp(&score(b))
                    .unwrap_or(std::cmp::Ordering::Equal)
            }) else {
                return 0;
            };
            let (b1, b2) = barycentric(v, p);
            let (m, mf) = (*m, *m as f64);
            let (x, y) = ((b1 * mf).max(0.0), (b2 * mf).max(0.0));
            let (i, j) = ((x as usize).min(m - 1), (y as usize).min(m - 1));
            let j = j.min(m - 1 - i);
            let i = i.min(m - 1 - j);
            let upper = x - i as f64 + (y - j as f64) > 1.0 && i + j + 1 < m;
            first + sub_index(m, i, j, upper)
        }
    }
}

/// (b1, b2) with p ≈ v0 + b1 (v1 − v0) + b2 (v2 − v0), by least squares in the plane.
fn barycentric(v: &[Vec3; 3], p: Vec3) -> (f64, f64) {
    let (e1, e2, d) = (v[1] - v[0], v[2] - v[0], p - v[0]);
    let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (d.dot(e1), d.dot(e2));
    let det = a * c - b * b;
    ((c * r1 - b * r2) / det, (a * r2 - b * r1) / det)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::TriangleMesh;
    use crate::geometry::quad::Quad;
    use crate::geometry::sphere::Sphere;

    #[test]
    fn sub_triangles_are_indexed_in_order_and_tile_the_area() {
        for m in 1..6 {
            for (n, (i, j, upper)) in sub_triangles(m).enumerate() {
                assert_eq!(sub_index(m, i, j, upper), n);
            }
            assert_eq!(sub_triangles(m).count(), m * m);
        }
    }

    #[test]
    fn every_patch_finds_itself_from_its_quadrature_points() {
        let quad = Shape::Quad(Quad {
            corner: Vec3::new(1.0, 0.0, 0.0),
            edge_u: Vec3::new(0.0, 3.0, 0.0),
            edge_v: Vec3::new(0.5, 0.0, 2.0),
            flip_normals: false,
        });
        let tri = Shape::Mesh(TriangleMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(0.3, 1.7, 0.2),
                Vec3::new(2.0, 2.0, 0.0),
            ],
            vec![[0, 1, 2], [1, 3, 2]],
            false,
        ));
        let shapes = vec![quad, tri];
        let (patches, cuts) = mesh(&shapes, 0.4).unwrap();
        let total: f64 = patches.iter().map(|p| p.area).sum();
        let expected = match (&shapes[0], &shapes[1]) {
            (Shape::Quad(q), Shape::Mesh(m)) => q.area() + m.area(),
            _ => unreachable!(),
        };
        assert!((total - expected).abs() < 1e-12 * expected);
        for (k, p) in patches.iter().enumerate() {
            for x in p.quadrature() {
                assert_eq!(patch_of(&cuts[p.shape as usize], x), k, "patch {k}");
            }
        }
    }

    #[test]
    fn spheres_and_huge_counts_are_refused_by_name() {
        let s = vec![Shape::Sphere(Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
            flip_normals: false,
        })];
        assert_eq!(mesh(&s, 0.1).unwrap_err(), MeshError::Sphere(0));
        let q = vec![Shape::Quad(Quad {
            corner: Vec3::ZERO,
            edge_u: Vec3::X * 1e3,
            edge_v: Vec3::Y * 1e3,
            flip_normals: false,
        })];
        let e = mesh(&q, 1e-3).unwrap_err();
        assert!(matches!(e, MeshError::TooMany { .. }), "{e}");
        let MeshError::TooMany { suggested, .. } = e else {
            unreachable!()
        };
        assert!(count(&q, suggested).unwrap() <= MAX_PATCHES);
    }
}
