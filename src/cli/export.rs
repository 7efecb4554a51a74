//! `furnace export`: a scene in another renderer's format.

use super::{write_file, Failure};
use anyhow::Context;
use clap::Args;
use furnace::scene::Scene;
use std::path::PathBuf;

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
    let written = if a.format == "pbrt-v4" {
        std::fs::create_dir_all(&a.out)
            .with_context(|| format!("cannot create {}", a.out.display()))?;
        let p = a.out.join("scene.pbrt");
        write_file(&p, &furnace::export::pbrt::export(&scene, "image.exr")?)?;
        p
    } else if a.format == "json" {
        furnace::export::json::write(&scene, &a.out)
            .with_context(|| format!("cannot export {}", a.scene.display()))?
    } else {
        furnace::export::mitsuba::write(&scene, &a.out)
            .with_context(|| format!("cannot export {}", a.scene.display()))?
    };
    super::say!("wrote {}", written.display());
    Ok(0)
}
