//! The committed reference exports' geometry against their sources, read without any of
//! furnace's code: the TOML by the `toml` crate, the exported XML's shapes and PLY files by
//! hand. For the measured Cornell Box the source is the page's geometry
//! (reference/cornell-box/cornell_box_geometry.toml); for every reference it is also its scene
//! file (`scene_file` in its JSON). Every exported triangle must be the source's, corners in the
//! source's order (so the winding, hence a one-sided light's side, is the source's), to within
//! f32 rounding, and every sphere its centre and radius; the Cornell Box's only deviation from
//! the page is the light lowered by 0.5 mm (scenes/cornell-box.toml, the light shape). A
//! negative control moves one vertex, reverses one winding and unlowers the light, and the
//! comparison must reject each.

use crate::root;

/// The export's shapes in order, by the source's section names (scenes/cornell-box.toml lists
/// them in this order).
const SURFACES: [&str; 8] = [
    "floor",
    "ceiling",
    "back_wall",
    "right_wall",
    "left_wall",
    "light",
    "short_block",
    "tall_block",
];

/// How far the light is lowered (mm; Mitsuba's cbox.xml `translate y = -0.5`).
const LIGHT_DROP: f64 = 0.5;

/// Largest corner difference accepted, relative to the coordinate (at least 1): the PLY holds
/// f32, whose spacing is at most 1.2e-7 relative (6.1e-5 mm at the Cornell Box's 560 mm).
const TOLERANCE: f64 = 1e-6;

type Triangle = [[f64; 3]; 3];

/// The source's triangles of one surface: each quad (v0, v1, v2, v3) as (v0, v1, v2) and
/// (v0, v2, v3), the page's diagonal (scenes/cornell-box.toml, the left wall).
fn source_triangles(src: &toml::Value, surface: &str) -> Vec<Triangle> {
    let section = &src[surface];
    let quads: Vec<Vec<[f64; 3]>> = match section.get("quads") {
        Some(q) => q
            .as_array()
            .unwrap()
            .iter()
            .map(|quad| quad.as_array().unwrap().iter().map(point).collect())
            .collect(),
        None => vec![section["vertices"]
            .as_array()
            .unwrap()
            .iter()
            .map(point)
            .collect()],
    };
    let drop = if surface == "light" { LIGHT_DROP } else { 0.0 };
    let mut out = Vec::new();
    for q in quads {
        assert_eq!(q.len(), 4, "{surface}: a quad has four corners");
        let q: Vec<[f64; 3]> = q.iter().map(|p| [p[0], p[1] - drop, p[2]]).collect();
        out.push([q[0], q[1], q[2]]);
        out.push([q[0], q[2], q[3]]);
    }
    out
}

/// A binary little-endian PLY of float x, y, z vertices and `uchar`-counted `int` faces, read
/// by hand: its triangles' corners.
fn ply_triangles(bytes: &[u8]) -> Result<Vec<Triangle>, String> {
    let end = b"end_header\n";
    let body = bytes
        .windows(end.len())
        .position(|w| w == end)
        .ok_or("no end_header")?
        + end.len();
    let header = std::str::from_utf8(&bytes[..body]).map_err(|e| e.to_string())?;
    let lines: Vec<&str> = header.lines().collect();
    let want_props = [
        "property float x",
        "property float y",
        "property float z",
        "property list uchar int vertex_indices",
    ];
    let count = |element: &str| -> Result<usize, String> {
        let line = lines
            .iter()
            .find(|l| l.starts_with(&format!("element {element} ")))
            .ok_or(format!("no element {element}"))?;
        line.rsplit(' ')
            .next()
            .unwrap()
            .parse()
            .map_err(|e| format!("{line}: {e}"))
    };
    if !lines.contains(&"format binary_little_endian 1.0")
        || want_props.iter().any(|p| !lines.contains(p))
        || lines.iter().filter(|l| l.starts_with("property")).count() != want_props.len()
    {
        return Err(format!("unexpected header:\n{header}"));
    }
    let (nv, nf) = (count("vertex")?, count("face")?);
    let mut at = body;
    let mut take = |n: usize| -> Result<&[u8], String> {
        let s = bytes.get(at..at + n).ok_or("truncated")?;
        at += n;
        Ok(s)
    };
    let mut vertices = Vec::with_capacity(nv);
    for _ in 0..nv {
        let mut p = [0.0; 3];
        for c in &mut p {
            *c = f64::from(f32::from_le_bytes(take(4)?.try_into().unwrap()));
        }
        vertices.push(p);
    }
    let mut triangles = Vec::with_capacity(nf);
    for _ in 0..nf {
        if take(1)?[0] != 3 {
            return Err("a face that is not a triangle".into());
        }
        let mut t = [[0.0; 3]; 3];
        for c in &mut t {
            let i = i32::from_le_bytes(take(4)?.try_into().unwrap());
            *c = *usize::try_from(i)
                .ok()
                .and_then(|i| vertices.get(i))
                .ok_or(format!("index {i} of {nv} vertices"))?;
        }
        triangles.push(t);
    }
    if at != bytes.len() {
        return Err(format!("{} bytes after the faces", bytes.len() - at));
    }
    Ok(triangles)
}

/// Whether two triangles are the same corners in the same cyclic order (the same winding),
/// each corner within [`TOLERANCE`].
fn same_triangle(a: &Triangle, b: &Triangle) -> bool {
    let close = |p: &[f64; 3], q: &[f64; 3]| {
        (0..3).all(|k| (p[k] - q[k]).abs() <= TOLERANCE * q[k].abs().max(1.0))
    };
    (0..3).any(|r| (0..3).all(|k| close(&a[(k + r) % 3], &b[k])))
}

/// Each exported surface's triangles against the source's, in order: the first disagreement.
fn compare(src: &toml::Value, exported: &[Vec<Triangle>]) -> Result<(), String> {
    if exported.len() != SURFACES.len() {
        return Err(format!(
            "{} shapes exported, {} surfaces",
            exported.len(),
            SURFACES.len()
        ));
    }
    for (surface, got) in SURFACES.iter().zip(exported) {
        let want = source_triangles(src, surface);
        if got.len() != want.len() {
            return Err(format!(
                "{surface}: {} triangles exported, {} in the source",
                got.len(),
                want.len()
            ));
        }
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            if !same_triangle(g, w) {
                return Err(format!(
                    "{surface} triangle {i}: exported {g:?}, source {w:?}"
                ));
            }
        }
    }
    Ok(())
}

/// An exported shape: a PLY's triangles, or a sphere's centre and radius.
#[derive(Debug, Clone, PartialEq)]
enum Exported {
    Mesh(Vec<Triangle>),
    Sphere([f64; 3], f64),
}

/// The value of attribute `name` in the XML element text `element`.
fn attr<'a>(element: &'a str, name: &str) -> &'a str {
    let key = format!(" {name}=\"");
    let at = element
        .find(&key)
        .unwrap_or_else(|| panic!("no {name} in {element}"))
        + key.len();
    &element[at..at + element[at..].find('"').unwrap()]
}

/// The element `<tag name="name" …/>` inside `shape`'s text.
fn child<'a>(shape: &'a str, tag: &str, name: &str) -> &'a str {
    let at = shape
        .find(&format!("<{tag} name=\"{name}\""))
        .unwrap_or_else(|| panic!("no <{tag} name={name:?}> in {shape}"));
    &shape[at..at + shape[at..].find("/>").unwrap()]
}

/// The committed export `dir`'s shapes in order, read by hand from its scene.xml (each
/// `<shape>` up to its `</shape>`) and its PLY files.
fn exported(dir: &str) -> Vec<Exported> {
    let dir = root(dir);
    let xml = std::fs::read_to_string(dir.join("scene.xml")).unwrap();
    let mut out = Vec::new();
    let mut rest = xml.as_str();
    while let Some(i) = rest.find("<shape type=\"") {
        let end = rest[i..].find("</shape>").unwrap() + i;
        let shape = &rest[i..end];
        out.push(match attr(shape, "type") {
            "ply" => {
                let file = attr(child(shape, "string", "filename"), "value");
                let bytes = std::fs::read(dir.join(file)).unwrap();
                Exported::Mesh(ply_triangles(&bytes).unwrap_or_else(|e| panic!("{file}: {e}")))
            }
            "sphere" => {
                let c = child(shape, "point", "center");
                let centre = ["x", "y", "z"].map(|k| attr(c, k).parse().unwrap());
                let radius = attr(child(shape, "float", "radius"), "value");
                Exported::Sphere(centre, radius.parse().unwrap())
            }
            other => panic!("unexpected shape type {other}"),
        });
        rest = &rest[end..];
    }
    out
}

/// The Cornell Box export's meshes.
fn cornell_meshes() -> Vec<Vec<Triangle>> {
    exported("reference/mitsuba/cornell-box.export")
        .into_iter()
        .map(|e| match e {
            Exported::Mesh(t) => t,
            other => panic!("a Cornell Box shape that is not a mesh: {other:?}"),
        })
        .collect()
}

/// A TOML number (integer or float).
fn number(v: &toml::Value) -> f64 {
    v.as_float()
        .or(v.as_integer().map(|i| i as f64))
        .unwrap_or_else(|| panic!("not a number: {v}"))
}

fn point(v: &toml::Value) -> [f64; 3] {
    let a = v.as_array().unwrap();
    assert_eq!(a.len(), 3, "{v}");
    std::array::from_fn(|k| number(&a[k]))
}

/// A scene file's shapes as its TOML states them: `triangles` (vertices and index triples),
/// `quad` (corner c, edges u and v: c, c + u, c + u + v, c + v, halved along c to c + u + v)
/// and `sphere`.
fn scene_shapes(src: &toml::Value) -> Vec<Exported> {
    src["shape"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| match t["type"].as_str().unwrap() {
            "triangles" => {
                let v: Vec<[f64; 3]> = t["vertices"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(point)
                    .collect();
                Exported::Mesh(
                    t["indices"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|i| {
                            let i = i.as_array().unwrap();
                            std::array::from_fn(|k| v[i[k].as_integer().unwrap() as usize])
                        })
                        .collect(),
                )
            }
            "quad" => {
                let (c, u, w) = (
                    point(&t["corner"]),
                    point(&t["edge_u"]),
                    point(&t["edge_v"]),
                );
                let at = |a: f64, b: f64| std::array::from_fn(|k| c[k] + a * u[k] + b * w[k]);
                let q = [at(0.0, 0.0), at(1.0, 0.0), at(1.0, 1.0), at(0.0, 1.0)];
                Exported::Mesh(vec![[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            }
            "sphere" => Exported::Sphere(point(&t["center"]), number(&t["radius"])),
            other => panic!("a reference scene with a {other} shape: extend this test"),
        })
        .collect()
}

fn source() -> toml::Value {
    let text =
        std::fs::read_to_string(root("reference/cornell-box/cornell_box_geometry.toml")).unwrap();
    toml::from_str(&text).unwrap()
}

#[test]
fn the_cornell_box_reference_export_has_the_measured_geometry() {
    let src = source();
    compare(&src, &cornell_meshes()).unwrap();
    // the page's winding, as Mitsuba reads it: the one-sided light's face normal
    // (v1 − v0) × (v2 − v0) points down, into the room
    for t in &cornell_meshes()[5] {
        let (e1, e2) = (
            [0, 1, 2].map(|k| t[1][k] - t[0][k]),
            [0, 1, 2].map(|k| t[2][k] - t[0][k]),
        );
        let ny = e1[2] * e2[0] - e1[0] * e2[2];
        assert!(ny < 0.0, "the light faces up: {t:?}");
    }
}

/// Negative control: a vertex moved by 1 mm, or one triangle's winding reversed, is rejected.
#[test]
fn a_moved_vertex_or_a_reversed_winding_fails_the_geometry_comparison() {
    let src = source();
    let mut moved = cornell_meshes();
    moved[4][1][2][0] += 1.0;
    let e = compare(&src, &moved).unwrap_err();
    assert!(e.starts_with("left_wall triangle 1"), "{e}");
    let mut reversed = cornell_meshes();
    reversed[5][0].swap(1, 2);
    let e = compare(&src, &reversed).unwrap_err();
    assert!(e.starts_with("light triangle 0"), "{e}");
    let mut unlowered = cornell_meshes();
    for t in &mut unlowered[5] {
        for p in t {
            p[1] += LIGHT_DROP;
        }
    }
    assert!(compare(&src, &unlowered).is_err());
}

/// Every committed reference export against its scene file (its JSON's `scene_file`), read by
/// the `toml` crate: the same shapes in order, each triangle in the source's winding, each
/// sphere's centre and radius.
#[test]
fn every_reference_export_has_its_scene_files_geometry() {
    let mut seen = 0;
    for entry in std::fs::read_dir(root("reference/mitsuba")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let meta: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let scene = meta["scene_file"].as_str().unwrap();
        let src: toml::Value = toml::from_str(&std::fs::read_to_string(root(scene)).unwrap())
            .unwrap_or_else(|e| panic!("{scene}: {e}"));
        let dir = path.with_extension("export");
        let got = exported(&dir.to_string_lossy());
        let want = scene_shapes(&src);
        assert_eq!(got.len(), want.len(), "{scene}: shapes");
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            match (g, w) {
                (Exported::Mesh(g), Exported::Mesh(w)) => {
                    assert_eq!(g.len(), w.len(), "{scene} shape {i}: triangles");
                    for (k, (a, b)) in g.iter().zip(w).enumerate() {
                        assert!(
                            same_triangle(a, b),
                            "{scene} shape {i} triangle {k}: exported {a:?}, source {b:?}"
                        );
                    }
                }
                (g, w) => assert_eq!(g, w, "{scene} shape {i}"),
            }
        }
        seen += 1;
    }
    assert!(seen >= 6, "{seen} references");
}
