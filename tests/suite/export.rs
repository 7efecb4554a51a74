//! The Mitsuba exporter: every bundled scene exports; the XML is well-formed and says what the
//! scene says (shapes, spectra, camera); every PLY reads back (with furnace's own PLY reader)
//! as the scene's geometry; and the exports committed next to the Mitsuba references are what
//! the exporter writes today, so a reference can never silently describe another scene.

use crate::root;
use furnace::export::mitsuba;
use furnace::geometry::Shape;
use furnace::io::mesh as meshio;
use furnace::lights::Light;
use furnace::scene::Scene;
use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Every bundled scene: scenes/*.toml and the manifests' scenes (templates filled with 0.5, a
/// wavelength band's `lo`/`hi` with 360/365 nm).
fn bundled() -> Vec<(PathBuf, Scene)> {
    let mut out = Vec::new();
    for dir in ["scenes", "tests/manifests/scenes"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(root(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .filter(|p| !p.to_string_lossy().ends_with(".regions.toml"))
            .collect();
        files.sort();
        for f in files {
            let mut text = std::fs::read_to_string(&f).unwrap();
            while let Some(i) = text.find("${") {
                let j = text[i..].find('}').unwrap() + i;
                let value = match &text[i + 2..j] {
                    "lo" => "360.0",
                    "hi" => "365.0",
                    _ => "0.5",
                };
                text.replace_range(i..=j, value);
            }
            let scene = Scene::parse(&text, &f).unwrap_or_else(|e| panic!("{e}"));
            out.push((f, scene));
        }
    }
    assert!(out.len() >= 14, "found only {} scenes", out.len());
    out
}

/// An element: name, attributes, children.
#[derive(Debug, Default, Clone)]
struct Node {
    name: String,
    attrs: BTreeMap<String, String>,
    children: Vec<Node>,
}

impl Node {
    fn all<'a>(&'a self, name: &str, out: &mut Vec<&'a Node>) {
        if self.name == name {
            out.push(self);
        }
        for c in &self.children {
            c.all(name, out);
        }
    }
    fn child_named(&self, tag: &str, name: &str) -> Option<&Node> {
        self.children
            .iter()
            .find(|c| c.name == tag && c.attrs.get("name").map(String::as_str) == Some(name))
    }
}

fn node(e: &BytesStart<'_>) -> Node {
    Node {
        name: e.name().as_ref().to_string(),
        attrs: e
            .attributes()
            .map(|a| {
                let a = a.unwrap();
                (
                    a.key.as_ref().to_string(),
                    a.normalized_value(XmlVersion::Explicit1_0)
                        .unwrap()
                        .into_owned(),
                )
            })
            .collect(),
        children: Vec::new(),
    }
}

/// Parses the whole document with quick-xml (which checks nesting and end tags).
fn parse(xml: &str) -> Node {
    let mut reader = Reader::from_str(xml);
    let mut stack = vec![Node::default()];
    loop {
        match reader
            .read_event()
            .unwrap_or_else(|e| panic!("not well-formed: {e}"))
        {
            Event::Eof => break,
            Event::Start(e) => stack.push(node(&e)),
            Event::Empty(e) => {
                let n = node(&e);
                stack.last_mut().unwrap().children.push(n);
            }
            Event::End(_) => {
                let n = stack.pop().unwrap();
                stack.last_mut().unwrap().children.push(n);
            }
            _ => {}
        }
    }
    assert_eq!(stack.len(), 1, "unclosed elements");
    let mut doc = stack.pop().unwrap();
    assert_eq!(doc.children.len(), 1, "one root element");
    doc.children.pop().unwrap()
}

/// `λ:v, …` or a plain number → (wavelength, value) pairs or a constant.
fn spectrum_points(value: &str) -> Vec<(Option<f64>, f64)> {
    value
        .split(',')
        .map(|p| match p.trim().split_once(':') {
            Some((l, v)) => (Some(l.parse().unwrap()), v.parse().unwrap()),
            None => (None, p.trim().parse().unwrap()),
        })
        .collect()
}

fn check_spectrum(node: &Node, name: &str, s: &furnace::spectrum::Spectrum, what: &str) {
    let n = node
        .child_named("spectrum", name)
        .unwrap_or_else(|| panic!("{what}: no <spectrum name={name:?}>"));
    if n.attrs.get("type").map(String::as_str) == Some("blackbody") {
        let t = n.child_named("float", "temperature").unwrap();
        assert!(
            matches!(s, furnace::spectrum::Spectrum::Blackbody { kelvin, scale }
            if *scale == 1.0 && t.attrs["value"].parse::<f64>().unwrap() == *kelvin)
        );
        return;
    }
    for (l, v) in spectrum_points(&n.attrs["value"]) {
        let at = l.unwrap_or(550.0);
        // Equal to rounding: the exporter's and this test's copies of the spectrum code may be
        // inlined differently (powi is not correctly rounded), 1 ulp apart.
        let e = s.eval(at);
        assert!(
            (v - e).abs() <= 4.0 * f64::EPSILON * e.abs(),
            "{what}: {name} at {at} nm: {v} vs {e}"
        );
    }
}

#[test]
fn every_bundled_scene_exports_and_reads_back() {
    for (path, scene) in bundled() {
        let what = path.display().to_string();
        let out = match mitsuba::export(&scene) {
            Ok(out) => out,
            // refused by name: Mitsuba 3's dielectrics have no dispersive index
            Err(e) if scene.bsdfs.iter().any(|b| b.separates_wavelengths()) => {
                assert!(e.to_string().contains("dispersive"), "{what}: {e}");
                continue;
            }
            // refused by name: Mitsuba 3's area emitter emits on one side only
            Err(e)
                if scene.lights.iter().any(|l| {
                    matches!(
                        l,
                        Light::Area {
                            two_sided: true,
                            ..
                        }
                    )
                }) =>
            {
                assert!(e.to_string().contains("two_sided"), "{what}: {e}");
                continue;
            }
            Err(e) => panic!("{what}: {e}"),
        };
        let doc = parse(&out.xml);
        assert_eq!(doc.name, "scene");
        assert_eq!(doc.attrs["version"], "3.0.0");
        // every medium exported once, by name, with sigma_t = σa + σs and albedo = σs/σt
        let media: Vec<&Node> = doc.children.iter().filter(|c| c.name == "medium").collect();
        assert_eq!(media.len(), scene.media.len(), "{what}");
        for (node, (m, name)) in media
            .iter()
            .zip(scene.media.iter().zip(&scene.medium_names))
        {
            assert_eq!(node.attrs["id"], format!("medium-{name}"), "{what}");
            assert_eq!(node.attrs["type"], "homogeneous", "{what}");
            let points = |key: &str| {
                spectrum_points(&node.child_named("spectrum", key).unwrap().attrs["value"])
            };
            for (l, t) in points("sigma_t") {
                let l = l.unwrap_or(550.0);
                let want = m.sigma_a.eval(l) + m.sigma_s.eval(l);
                assert!(
                    (t - want).abs() <= 1e-12 * want.abs().max(1.0),
                    "{what}: sigma_t {t} vs {want} at {l}"
                );
            }
            for (l, a) in points("albedo") {
                let l = l.unwrap_or(550.0);
                let t = m.sigma_a.eval(l) + m.sigma_s.eval(l);
                let want = if t > 0.0 { m.sigma_s.eval(l) / t } else { 0.0 };
                assert!(
                    (a - want).abs() <= 1e-12,
                    "{what}: albedo {a} vs {want} at {l}"
                );
            }
        }
        let integrator = doc
            .children
            .iter()
            .find(|c| c.name == "integrator")
            .unwrap();
        let want = if scene.media.iter().any(|m| !m.is_constant()) {
            "volpathmis"
        } else if scene.has_media() {
            "volpath"
        } else {
            "path"
        };
        assert_eq!(integrator.attrs["type"], want, "{what}");
        let shapes: Vec<&Node> = doc.children.iter().filter(|c| c.name == "shape").collect();
        assert_eq!(shapes.len(), scene.aggregate.shapes().len(), "{what}");
        let meshes: BTreeMap<&str, &Vec<u8>> =
            out.meshes.iter().map(|(n, b)| (n.as_str(), b)).collect();
        let dir = tempdir(&path);
        for (i, (shape, node)) in scene.aggregate.shapes().iter().zip(&shapes).enumerate() {
            let what = format!("{what} shape[{i}]");
            match shape {
                Shape::Sphere(s) => {
                    assert_eq!(node.attrs["type"], "sphere", "{what}");
                    let c = node.child_named("point", "center").unwrap();
                    let xyz: Vec<f64> = ["x", "y", "z"]
                        .iter()
                        .map(|k| c.attrs[*k].parse().unwrap())
                        .collect();
                    assert_eq!(xyz, s.center.to_array().to_vec(), "{what}");
                    let r: f64 = node.child_named("float", "radius").unwrap().attrs["value"]
                        .parse()
                        .unwrap();
                    assert_eq!(r, s.radius, "{what}");
                }
                Shape::Quad(_) | Shape::Mesh(_) => {
                    assert_eq!(node.attrs["type"], "ply", "{what}");
                    assert_eq!(
                        node.child_named("boolean", "face_normals").unwrap().attrs["value"],
                        "true"
                    );
                    let file = &node.child_named("string", "filename").unwrap().attrs["value"];
                    let bytes = meshes[file.as_str()];
                    let p = dir.join(file.replace('/', "_"));
                    std::fs::write(&p, bytes).unwrap();
                    let back = meshio::load_mesh(&p).unwrap_or_else(|e| panic!("{what}: {e}"));
                    // The triangles furnace renders, as world-space corners.
                    let (want, flip): (Vec<[furnace::math::Vec3; 3]>, bool) = match shape {
                        Shape::Quad(q) => {
                            let c = q.corner;
                            let (a, b, d) = (c + q.edge_u, c + q.edge_u + q.edge_v, c + q.edge_v);
                            (vec![[c, a, b], [c, b, d]], q.flip_normals)
                        }
                        Shape::Mesh(m) => (
                            (0..m.triangles.len()).map(|t| m.vertices(t)).collect(),
                            m.flip_normals,
                        ),
                        Shape::Sphere(_) => unreachable!(),
                    };
                    assert_eq!(back.triangles.len(), want.len(), "{what}");
                    for (t, w) in back.triangles.iter().zip(&want) {
                        for k in 0..3 {
                            let got = back.positions[t[k] as usize];
                            for (g, e) in got.iter().zip(w[k].to_array()) {
                                // f32 storage: relative 2^-24.
                                assert!((g - e).abs() <= 1e-7 * e.abs().max(1.0), "{what}");
                            }
                        }
                    }
                    assert_eq!(
                        node.child_named("boolean", "flip_normals").unwrap().attrs["value"],
                        flip.to_string(),
                        "{what}"
                    );
                }
            }
            let bsdf = node.children.iter().find(|c| c.name == "bsdf").unwrap();
            use furnace::scattering::{Bsdf, ConductorFresnel, Ior};
            match &scene.bsdfs[i] {
                Bsdf::Diffuse(l) => {
                    assert_eq!(bsdf.attrs["type"], "twosided", "{what}");
                    check_spectrum(&bsdf.children[0], "reflectance", &l.reflectance, &what);
                }
                Bsdf::Conductor(c) => {
                    assert_eq!(bsdf.attrs["type"], "twosided", "{what}");
                    let inner = &bsdf.children[0];
                    let kind = if c.is_smooth() {
                        "conductor"
                    } else {
                        "roughconductor"
                    };
                    assert_eq!(inner.attrs["type"], kind, "{what}");
                    if let ConductorFresnel::Complex { eta, k } = &c.fresnel {
                        check_spectrum(inner, "eta", eta, &what);
                        check_spectrum(inner, "k", k, &what);
                    }
                    if let Some(g) = &c.microfacet {
                        let a = &inner.child_named("float", "alpha").unwrap().attrs["value"];
                        assert_eq!(a.parse::<f64>().unwrap(), g.alpha_x, "{what}");
                    }
                }
                Bsdf::Dielectric(d) => {
                    let kind = if d.is_smooth() {
                        "dielectric"
                    } else {
                        "roughdielectric"
                    };
                    assert_eq!(bsdf.attrs["type"], kind, "{what}");
                    let Ior::Constant(n) = d.ior else {
                        panic!("{what}: dispersive")
                    };
                    let v = &bsdf.child_named("float", "int_ior").unwrap().attrs["value"];
                    assert_eq!(v.parse::<f64>().unwrap(), n, "{what}");
                }
                Bsdf::Ward(_) => panic!("{what}: Ward is not exportable"),
                Bsdf::Null(_) => assert_eq!(bsdf.attrs["type"], "null", "{what}"),
            }
            // media on either side: references to the exported media, by name
            let b = scene.shape_media[i];
            for (side, m) in [
                ("interior", b.and_then(|b| b.interior)),
                ("exterior", b.and_then(|b| b.exterior)),
            ] {
                let r = node.children.iter().find(|c| {
                    c.name == "ref" && c.attrs.get("name").map(String::as_str) == Some(side)
                });
                match m {
                    None => assert!(r.is_none(), "{what}: unexpected {side}"),
                    Some(m) => assert_eq!(
                        r.expect("medium reference").attrs["id"],
                        format!("medium-{}", scene.medium_names[m as usize]),
                        "{what}"
                    ),
                }
            }
            let emitter = node.children.iter().find(|c| c.name == "emitter");
            match scene.shape_light[i] {
                None => assert!(emitter.is_none(), "{what}"),
                Some(li) => {
                    let furnace::lights::Light::Area { radiance, .. } = &scene.lights[li as usize]
                    else {
                        panic!("{what}: not an area light")
                    };
                    let e = emitter.unwrap();
                    assert_eq!(e.attrs["type"], "area");
                    check_spectrum(e, "radiance", radiance, &what);
                }
            }
        }
        let mut sensors = Vec::new();
        doc.all("sensor", &mut sensors);
        assert_eq!(sensors.len(), 1, "{what}");
        let fov: f64 = sensors[0].child_named("float", "fov").unwrap().attrs["value"]
            .parse()
            .unwrap();
        assert_eq!(fov, scene.camera.fov_y, "{what}");
        let lights = doc.children.iter().filter(|c| c.name == "emitter").count();
        let non_area = scene
            .lights
            .iter()
            .filter(|l| !matches!(l, furnace::lights::Light::Area { .. }))
            .count();
        assert_eq!(lights, non_area, "{what}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

fn tempdir(scene: &Path) -> PathBuf {
    let d = crate::scratch_dir().join(format!(
        "furnace-export-{}-{}",
        std::process::id(),
        scene.file_stem().unwrap().to_string_lossy()
    ));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn committed_reference_exports_are_current() {
    for (scene, export) in [
        (
            "scenes/cornell-box.toml",
            "reference/mitsuba/cornell-box.export",
        ),
        (
            "scenes/furnace-sphere.toml",
            "reference/mitsuba/furnace-sphere.export",
        ),
        (
            "scenes/cornell-glossy.toml",
            "reference/mitsuba/cornell-glossy.export",
        ),
        (
            "tests/manifests/scenes/furnace-box-0.5.toml",
            "reference/mitsuba/furnace-box.export",
        ),
        (
            "scenes/rayleigh-sky.toml",
            "reference/mitsuba/rayleigh-sky.export",
        ),
        ("scenes/hg-fog.toml", "reference/mitsuba/hg-fog.export"),
    ] {
        let s = Scene::load(&root(scene)).unwrap();
        let out = mitsuba::export(&s).unwrap();
        let dir = root(export);
        let committed = std::fs::read_to_string(dir.join("scene.xml")).unwrap();
        assert_eq!(
            committed, out.xml,
            "{export}/scene.xml is stale: the scene or the exporter changed; regenerate the reference (reference/mitsuba/README.md)"
        );
        for (rel, bytes) in &out.meshes {
            assert_eq!(
                &std::fs::read(dir.join(rel)).unwrap(),
                bytes,
                "{export}/{rel}"
            );
        }
    }
}

/// The committed Cornell Box export against the scene's sources read here, without furnace's
/// scene loader (the TOML by the `toml` crate, the CSV tables by hand), so that a misreading in
/// the loader cannot reach both the reference render and furnace's image unseen: the camera's
/// frame and its fov from the focal length and film height (fov_y = 2 atan(h / 2f)), and every
/// reflectance and emission spectrum at each wavelength the XML lists.
#[test]
fn the_cornell_box_reference_export_says_what_its_sources_say() {
    let text = std::fs::read_to_string(root("scenes/cornell-box.toml")).unwrap();
    let src: toml::Value = toml::from_str(&text).unwrap();
    let xml =
        std::fs::read_to_string(root("reference/mitsuba/cornell-box.export/scene.xml")).unwrap();
    let doc = parse(&xml);
    let nums = |v: &toml::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_float().or(x.as_integer().map(|i| i as f64)).unwrap())
            .collect()
    };
    let cam = &src["camera"];
    let mut sensors = Vec::new();
    doc.all("sensor", &mut sensors);
    let sensor = sensors[0];
    let fov: f64 = sensor.child_named("float", "fov").unwrap().attrs["value"]
        .parse()
        .unwrap();
    let (f, h) = (
        cam["focal_length"].as_float().unwrap(),
        nums(&cam["film_size"])[1],
    );
    let want = 2.0 * (h / (2.0 * f)).atan().to_degrees();
    assert!((fov - want).abs() < 1e-12, "fov {fov} vs {want}");
    assert_eq!(
        sensor.child_named("string", "fov_axis").unwrap().attrs["value"],
        "y"
    );
    let mut lookats = Vec::new();
    sensor.all("lookat", &mut lookats);
    let xyz = |s: &str| -> Vec<f64> { s.split(',').map(|v| v.trim().parse().unwrap()).collect() };
    for (attr, key) in [("origin", "position"), ("target", "look_at"), ("up", "up")] {
        assert_eq!(
            xyz(&lookats[0].attrs[attr]),
            nums(&cam[key]),
            "camera {key}"
        );
    }
    // the CSV tables, read by hand: header, then wavelength and one value per column
    let table = |spec: &toml::Value| -> Vec<(f64, f64)> {
        let csv =
            std::fs::read_to_string(root("scenes").join(spec["csv"].as_str().unwrap())).unwrap();
        let mut lines = csv
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.starts_with('#'));
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = header
            .iter()
            .position(|c| c.trim() == spec["column"].as_str().unwrap())
            .unwrap();
        lines
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
                (v[0], v[col])
            })
            .collect()
    };
    // each shape, in order, against its material's reflectance and its emission as the TOML
    // names them: a constant, or a CSV column
    let spectra = src["spectra"].as_table().unwrap();
    let expect = |v: &toml::Value, points: &[(Option<f64>, f64)], what: &str| {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
        match v {
            toml::Value::Float(c) => assert!(
                matches!(points, [(None, x)] if close(*x, *c)),
                "{what}: {points:?} vs the constant {c}"
            ),
            toml::Value::String(name) => {
                let t = table(&spectra[name.as_str()]);
                assert_eq!(points.len(), t.len(), "{what}: wavelengths");
                for (&(l, x), &(tl, tv)) in points.iter().zip(&t) {
                    assert!(
                        l == Some(tl) && close(x, tv),
                        "{what} at {tl} nm: {x} vs {tv}"
                    );
                }
            }
            other => panic!("{what}: unexpected {other:?}"),
        }
    };
    let mut shapes = Vec::new();
    doc.all("shape", &mut shapes);
    let src_shapes = src["shape"].as_array().unwrap();
    assert_eq!(shapes.len(), src_shapes.len());
    for (i, (x, t)) in shapes.iter().zip(src_shapes).enumerate() {
        let material = &src["materials"][t["material"].as_str().unwrap()];
        let mut refl = Vec::new();
        x.all("spectrum", &mut refl);
        let r = refl
            .iter()
            .find(|n| n.attrs["name"] == "reflectance")
            .unwrap_or_else(|| panic!("shape {i}: no reflectance"));
        expect(
            &material["reflectance"],
            &spectrum_points(&r.attrs["value"]),
            &format!("shape {i} reflectance"),
        );
        match t.get("emission") {
            Some(e) => {
                let radiance = refl.iter().find(|n| n.attrs["name"] == "radiance").unwrap();
                expect(
                    e,
                    &spectrum_points(&radiance.attrs["value"]),
                    &format!("shape {i} emission"),
                );
            }
            None => assert!(
                refl.iter().all(|n| n.attrs["name"] != "radiance"),
                "shape {i} emits"
            ),
        }
    }
}

#[test]
fn pbrt_export_snapshot_and_every_scene() {
    for (path, scene) in bundled() {
        if scene.has_media() {
            let e = furnace::export::pbrt::export(&scene, "out.exr").unwrap_err();
            assert!(e.to_string().contains("participating media"), "{e}");
            continue;
        }
        let text = furnace::export::pbrt::export(&scene, "out.exr").unwrap();
        // Every shape in its own attribute block, every emitter with its luminance scale.
        assert_eq!(
            text.matches("AttributeBegin").count(),
            scene.aggregate.shapes().len(),
            "{}",
            path.display()
        );
        assert_eq!(
            text.matches("AttributeBegin").count(),
            text.matches("AttributeEnd").count()
        );
        assert!(
            !text
                .split_whitespace()
                .any(|t| ["NaN", "inf", "-inf"].contains(&t)),
            "{}",
            path.display()
        );
    }
    let s = Scene::load(&root("scenes/cornell-box.toml")).unwrap();
    insta::assert_snapshot!(
        "pbrt_cornell_box",
        furnace::export::pbrt::export(&s, "cbox.exr").unwrap()
    );
    let s = Scene::load(&root("scenes/furnace-sphere.toml")).unwrap();
    insta::assert_snapshot!(
        "pbrt_furnace_sphere",
        furnace::export::pbrt::export(&s, "sphere.exr").unwrap()
    );
}

#[test]
fn two_sided_emission_is_refused_by_name() {
    let text = std::fs::read_to_string(root("scenes/furnace-sphere.toml"))
        .unwrap()
        .replace(
            "flip_normals = true",
            "flip_normals = true\ntwo_sided = true",
        );
    let s = Scene::parse(&text, Path::new("two-sided.toml")).unwrap();
    let e = mitsuba::export(&s).unwrap_err().to_string();
    assert!(
        e.contains("shape[0] emission with two_sided = true") && e.contains("Mitsuba 3"),
        "{e}"
    );
}

#[test]
fn a_purely_absorbing_chromatic_medium_exports_a_uniform_albedo() {
    // Mitsuba 3.9.1 refuses a tabulated albedo that is zero everywhere ("ContinuousDistribution:
    // no probability mass found") but takes the uniform 0 that means the same.
    let path = root("tests/manifests/scenes/absorber.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("${sigma}", "1.0");
    let s = Scene::parse(&text, &path).unwrap();
    let doc = parse(&mitsuba::export(&s).unwrap().xml);
    let medium = doc.children.iter().find(|c| c.name == "medium").unwrap();
    let albedo = &medium.child_named("spectrum", "albedo").unwrap().attrs["value"];
    assert_eq!(albedo, "0");
    // σt still varies with wavelength
    let sigma_t = &medium.child_named("spectrum", "sigma_t").unwrap().attrs["value"];
    assert!(sigma_t.starts_with("360:2,"), "{sigma_t}");
}

#[test]
fn anisotropic_roughness_is_refused_by_name_in_pbrt_and_mitsuba() {
    // pbrt's u/v and Mitsuba's tangent frame are not furnace's: α_x ≠ α_y would not line up
    let text = std::fs::read_to_string(root("scenes/cornell-glossy.toml"))
        .unwrap()
        .replace(
            "ior = 1.5\nalpha = 0.15",
            "ior = 1.5\nalpha_x = 0.1\nalpha_y = 0.3",
        );
    let s = Scene::parse(&text, &root("scenes/cornell-glossy.toml")).unwrap();
    let e = furnace::export::pbrt::export(&s, "out.exr")
        .unwrap_err()
        .to_string();
    assert!(e.contains("anisotropic roughness"), "{e}");
    let e = furnace::export::mitsuba::export(&s)
        .unwrap_err()
        .to_string();
    assert!(e.contains("anisotropic roughness"), "{e}");
}
