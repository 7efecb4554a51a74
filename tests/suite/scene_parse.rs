//! Parsed scenes, snapshotted with insta: what a scene file turns into.

use crate::root;
use furnace::geometry::Shape;
use furnace::scene::Scene;
use std::path::Path;

const SMALL: &str = r#"
[render]
width = 32
height = 24
spp = 4
max_depth = 3

[camera]
position = [0, 1, -5]
look_at = [0, 1, 0]
up = [0, 1, 0]
fov = 40

[spectra]
warm = { blackbody = 3000, scale = 1e-6 }
paint = { wavelengths = [400, 700], values = [0.2, 0.8], outside = "clamp" }

[materials.white]
type = "diffuse"
reflectance = 0.75

[materials.paint]
type = "diffuse"
reflectance = "paint"

[[shape]]
type = "quad"
corner = [-1, 0, -1]
edge_u = [0, 0, 2]
edge_v = [2, 0, 0]
material = "white"

[[shape]]
type = "sphere"
center = [0, 1, 0]
radius = 0.5
material = "paint"

[[shape]]
type = "triangles"
vertices = [[-0.5, 2.5, -0.5], [0.5, 2.5, -0.5], [0.5, 2.5, 0.5]]
indices = [[0, 2, 1]]
material = "white"
emission = "warm"

[[light]]
type = "point"
position = [0, 3, -2]
intensity = 2.5

[[light]]
type = "environment"
radiance = 0.01
"#;

#[test]
fn small_scene_parses_to_the_expected_model() {
    let scene = Scene::parse(SMALL, Path::new("small.toml")).unwrap();
    insta::assert_debug_snapshot!(
        "small_scene",
        (
            &scene.render,
            &scene.camera,
            &scene.bsdfs,
            &scene.lights,
            &scene.shape_light
        )
    );
    let shapes: Vec<String> = scene
        .aggregate
        .shapes()
        .iter()
        .map(|s| match s {
            Shape::Sphere(_) => format!("sphere area {:.6}", s.area()),
            Shape::Quad(_) => format!("quad area {:.6}", s.area()),
            Shape::Mesh(m) => format!(
                "mesh {} triangles area {:.6} normal {:?}",
                m.triangles.len(),
                s.area(),
                m.normal(0)
            ),
        })
        .collect();
    insta::assert_debug_snapshot!("small_scene_shapes", shapes);
}

#[test]
fn cornell_box_summary() {
    let scene = Scene::load(&root("scenes/cornell-box.toml")).unwrap();
    let summary: Vec<String> = scene
        .aggregate
        .shapes()
        .iter()
        .zip(&scene.shape_light)
        .map(|(s, l)| {
            let kind = match s {
                Shape::Mesh(m) => format!("{} triangles", m.triangles.len()),
                Shape::Quad(_) => "quad".into(),
                Shape::Sphere(_) => "sphere".into(),
            };
            format!("{kind}, area {:.1} mm², emitter: {}", s.area(), l.is_some())
        })
        .collect();
    insta::assert_debug_snapshot!(
        "cornell_box_summary",
        (&scene.render, &scene.camera, summary)
    );
}

/// Shapes share a material index exactly when they name the same material (the path tracer
/// evaluates each material's spectra once per path by it); planar shapes are recognised.
#[test]
fn shapes_of_one_material_share_its_index_and_flat_shapes_are_planar() {
    let scene = Scene::parse(SMALL, Path::new("small.toml")).unwrap();
    // materials in name order: paint, white
    assert_eq!(scene.material_of, vec![1, 0, 1]);
    let planar =
        |s: &Scene| -> Vec<bool> { s.aggregate.shapes().iter().map(Shape::is_planar).collect() };
    assert_eq!(planar(&scene), vec![true, false, true]);
    let cornell = Scene::load(&root("scenes/cornell-box.toml")).unwrap();
    // floor, ceiling, back wall, green wall, red wall (the measured wall is not flat: its
    // fourth corner lies 3.2 mm off the plane of the other three), light, two blocks
    assert_eq!(
        planar(&cornell),
        vec![true, true, true, true, false, true, false, false]
    );
    let m = &cornell.material_of;
    assert!(m[0] == m[1] && m[1] == m[2] && m[2] == m[6] && m[6] == m[7]);
    assert!(m[3] != m[0] && m[4] != m[0] && m[3] != m[4] && m[5] != m[0]);
}

/// The complete example of docs/scenes.md is a valid scene (parsed as if it lived in scenes/).
#[test]
fn readme_scene_example_is_valid() {
    let readme = std::fs::read_to_string(root("docs/scenes.md")).unwrap();
    let section = readme
        .split("## A complete example")
        .nth(1)
        .expect("docs/scenes.md has a complete-example section");
    let block = section
        .split("```toml")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("a toml block");
    let scene =
        Scene::parse(block, &root("scenes/readme-example.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.aggregate.shapes().len(), 5);
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(scene.medium_names, ["fog"]);
    assert!(scene
        .camera
        .build(scene.render.width, scene.render.height)
        .is_ok());
}
