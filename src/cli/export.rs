//! `furnace export`: a scene in another renderer's format.

use super::Failure;
use anyhow::Context;
use clap::Args;
use furnace::scene::Scene;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct ExportArgs {
    /// The furnace scene (TOML).
    scene: PathBuf,
    /// Target format: mitsuba3 (scene.xml + meshes/*.ply), json (scene.json, furnace's scene interchange JSON for the Cycles and LuxCore drivers, docs/scene-json.md) or pbrt-v4 (scene.pbrt, meshes inline; not verified with a pbrt build).
    #[arg(long, default_value = "mitsuba3", value_parser = ["mitsuba3", "json", "pbrt-v4"])]
    format: String,
    /// Output folder (created); the scene file inside it is scene.xml, scene.json or scene.pbrt.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `furnace export`; returns the exit code.
pub fn run(a: ExportArgs) -> Result<i32, Failure> {
    let scene =
        Scene::load(&a.scene).with_context(|| format!("invalid scene {}", a.scene.display()))?;
    let exported = match a.format.as_str() {
        "pbrt-v4" => furnace::export::pbrt::export(&scene, "image.exr")
            .map(|text| vec![(PathBuf::from("scene.pbrt"), text.into_bytes())]),
        "json" => furnace::export::json::files(&scene),
        _ => furnace::export::mitsuba::files(&scene),
    };
    let files = exported.with_context(|| format!("cannot export {}", a.scene.display()))?;
    // nothing the export writes may be the scene or a file it reads (an --out in the scene's
    // own folder could otherwise replace its meshes), and every output must be writable,
    // before anything is written
    let outputs: Vec<PathBuf> = files.iter().map(|(rel, _)| a.out.join(rel)).collect();
    let outputs: Vec<(&str, &Path)> = outputs
        .iter()
        .map(|p| ("an exported file", p.as_path()))
        .collect();
    super::distinct_paths(&super::scene_inputs(&a.scene, &scene), &outputs)?;
    let written = furnace::export::write_files(&a.out, &files)
        .with_context(|| format!("cannot export {}", a.scene.display()))?;
    super::say!("wrote {}", written.display());
    Ok(0)
}
