//! External renderers: a renderer described in TOML (`renderers.toml`) is driven through a
//! command template, fed a scene exported to its format, and its EXR output is turned into a
//! [`Film`] so that every renderer-agnostic check applies exactly the same statistics to it.
//!
//! ```toml
//! [renderer.mitsuba3]
//! description = "Mitsuba 3 from PyPI through reference/mitsuba/render.py"
//! exporter = "mitsuba3"                 # scene format (furnace export --format)
//! observer = "mitsuba3"                 # colour pipeline of its RGB output
//! channels = ["R", "G", "B"]            # linear-sRGB channel names in its EXR
//! variant = "scalar_spectral"           # default for {variant}; `--renderer mitsuba3:VARIANT`
//! batches = 4                           # independent runs per image (standard error)
//! probe = ["python3", "-c", "import mitsuba"]   # availability test
//! env = { DRJIT_LIBLLVM_PATH = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1" }  # for llvm_* variants
//! command = ["python3", "reference/mitsuba/render.py", "--xml", "{scene}", "--out", "{out}",
//!            "--spp", "{spp}", "--seed", "{seed}", "--width", "{width}", "--height", "{height}",
//!            "--max-depth", "{max_depth}", "--variant", "{variant}", "--threads", "{threads}"]
//! ```
//!
//! Statistics for a black box: one run gives one image, not per-sample moments, so each image
//! is rendered as `batches` independent runs (seeds derived from the check's seed) of
//! spp/batches samples; each pixel's K run values are its samples, so the per-pixel variance of
//! the mean has K − 1 degrees of freedom. The checks' variance diagnosis (batch means over
//! pixels and a Hill tail index, `stats::stability`) and, for uniform regions, the between-pixel
//! standard error (the larger of the two is used) apply unchanged.
//!
//! Colour: the output's R, G, B are taken in the renderer's declared pipeline (`observer`);
//! X, Y, Z are recovered with that pipeline's inverse matrix and rescaled by the ratio of the
//! white points' Y (furnace's 1 nm ∫ȳ over the renderer's normalisation; 1/1.00100 for
//! Mitsuba 3), so a flat spectrum reads the same Y in both and the analytic checks' closed
//! forms apply exactly to grey scenes. When a check asks for another pipeline's RGB, the RGB
//! is converted through XYZ (exact for flat spectra only).

use super::renderer::{Renderer, RendererError};
use crate::export;
use crate::film::Film;
use crate::integrators::Strategy;
use crate::io::image as io;
use crate::render::RenderSettings;
use crate::scene::{Scene, Source};
use crate::spectrum::Observer;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};

/// One `[renderer.NAME]` table.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RendererDesc {
    /// What it is, for reports.
    #[serde(default)]
    pub description: Option<String>,
    /// Scene format: `mitsuba3`.
    pub exporter: String,
    /// Colour pipeline of the RGB it writes: `mitsuba3` or `cie1931`.
    pub observer: String,
    /// Names of its linear R, G, B channels.
    #[serde(default)]
    pub channels: Option<[String; 3]>,
    /// Default `{variant}`.
    #[serde(default)]
    pub variant: Option<String>,
    /// Independent runs per image (≥ 2).
    #[serde(default)]
    pub batches: Option<u32>,
    /// A command that succeeds when the renderer is installed.
    #[serde(default)]
    pub probe: Option<Vec<String>>,
    /// Environment variables set for the probe and the command (a variable already set in
    /// furnace's environment wins, so a user can override without editing the file).
    #[serde(default)]
    pub env: BTreeMap<String, String>,
    /// The argv template; placeholders {scene} {out} {spp} {seed} {width} {height}
    /// {max_depth} {variant} {threads}.
    pub command: Vec<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderersFile {
    #[serde(default)]
    renderer: BTreeMap<String, RendererDesc>,
}

/// Placeholders a command template may use.
pub const PLACEHOLDERS: [&str; 9] = [
    "scene",
    "out",
    "spp",
    "seed",
    "width",
    "height",
    "max_depth",
    "variant",
    "threads",
];

/// Reads a renderers file; errors give file:line:column or name the renderer and key.
pub fn load_renderers(path: &Path) -> Result<BTreeMap<String, RendererDesc>, String> {
    let text = crate::io::read_text(path, "the renderers file").map_err(|e| e.to_string())?;
    let f: RenderersFile =
        crate::io::parse_toml(&Source { path, text: &text }).map_err(|e| e.to_string())?;
    for (name, d) in &f.renderer {
        let at = |k: &str, m: String| format!("{}: renderer.{name}.{k}: {m}", path.display());
        if d.exporter != "mitsuba3" {
            return Err(at(
                "exporter",
                format!("{:?}; allowed: \"mitsuba3\"", d.exporter),
            ));
        }
        if Observer::from_name(&d.observer).is_none() {
            return Err(at(
                "observer",
                format!("{:?}; allowed: \"cie1931\", \"mitsuba3\"", d.observer),
            ));
        }
        if d.batches.is_some_and(|b| !(2..=1024).contains(&b)) {
            return Err(at(
                "batches",
                format!(
                    "{}: need 2..=1024 independent runs for a standard error",
                    d.batches.unwrap_or(0)
                ),
            ));
        }
        if d.command.is_empty() {
            return Err(at("command", "empty; give the argv template".into()));
        }
        for arg in &d.command {
            let mut rest = arg.as_str();
            while let Some(i) = rest.find('{') {
                let j = rest[i..]
                    .find('}')
                    .map(|j| i + j)
                    .ok_or_else(|| at("command", format!("{arg:?} has an unclosed '{{'")))?;
                let key = &rest[i + 1..j];
                if !PLACEHOLDERS.contains(&key) {
                    return Err(at(
                        "command",
                        format!(
                            "unknown placeholder {{{key}}} in {arg:?}; allowed: {}",
                            PLACEHOLDERS.map(|p| format!("{{{p}}}")).join(" ")
                        ),
                    ));
                }
                rest = &rest[j + 1..];
            }
        }
    }
    Ok(f.renderer)
}

/// An external renderer ready to run.
#[derive(Debug)]
pub struct External {
    /// `NAME` or `NAME:VARIANT`.
    pub label: String,
    /// Its description.
    pub desc: RendererDesc,
    /// `{variant}`.
    pub variant: String,
    /// Working directory of the command (relative paths in the template resolve here).
    pub workdir: PathBuf,
    counter: AtomicU64,
}

impl External {
    /// The renderer `spec` (`NAME` or `NAME:VARIANT`) from `renderers`.
    pub fn from_spec(
        spec: &str,
        renderers: &BTreeMap<String, RendererDesc>,
        workdir: &Path,
    ) -> Result<External, String> {
        let (name, variant) = match spec.split_once(':') {
            Some((n, v)) => (n, Some(v.to_string())),
            None => (spec, None),
        };
        let desc = renderers.get(name).ok_or_else(|| {
            format!(
                "unknown renderer {name:?}; known: furnace{}",
                renderers
                    .keys()
                    .map(|k| format!(", {k}"))
                    .collect::<String>()
            )
        })?;
        let variant = variant.or(desc.variant.clone()).unwrap_or_default();
        Ok(External {
            label: if variant.is_empty() {
                name.to_string()
            } else {
                format!("{name}:{variant}")
            },
            desc: desc.clone(),
            variant,
            workdir: workdir.to_path_buf(),
            counter: AtomicU64::new(0),
        })
    }

    /// Runs the probe; Err(message) when the renderer is not available.
    pub fn probe(&self) -> Result<(), String> {
        let Some(p) = &self.desc.probe else {
            return Ok(());
        };
        let out = self
            .command(p)
            .output()
            .map_err(|e| format!("cannot run {:?}: {e}", p.join(" ")))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!(
                "{:?} failed: {}",
                p.join(" "),
                tail(&String::from_utf8_lossy(&out.stderr))
            ))
        }
    }

    /// A process for `argv` in the working directory with the renderer's environment.
    fn command(&self, argv: &[String]) -> Command {
        let mut c = Command::new(&argv[0]);
        c.args(&argv[1..]).current_dir(&self.workdir);
        for (k, v) in &self.desc.env {
            if std::env::var_os(k).is_none() {
                c.env(k, v);
            }
        }
        c
    }

    /// Independent runs per image.
    pub fn batches(&self) -> u64 {
        self.desc.batches.unwrap_or(4) as u64
    }
}

fn tail(s: &str) -> String {
    let lines: Vec<&str> = s.lines().rev().take(3).collect();
    lines.into_iter().rev().collect::<Vec<_>>().join(" | ")
}

impl Renderer for External {
    fn name(&self) -> String {
        self.label.clone()
    }

    fn is_reference(&self) -> bool {
        false
    }

    fn render(&self, scene: &Scene, s: &RenderSettings) -> Result<Film, RendererError> {
        self.render_batches(scene, s).map_err(RendererError)
    }
}

impl External {
    /// Renders the image as `batches` independent runs of the command.
    fn render_batches(&self, scene: &Scene, s: &RenderSettings) -> Result<Film, String> {
        if s.integrator.strategy != Strategy::Mis {
            return Err(format!(
                "{} runs its own estimator; checks that select BSDF-only or light-only sampling do not apply",
                self.label
            ));
        }
        let native = Observer::from_name(&self.desc.observer).unwrap_or_default();
        if matches!(s.observer, Observer::Responses(_)) {
            return Err(format!(
                "{} writes RGB only; band responses (the measured kind) need a spectral film",
                self.label
            ));
        }
        let k = self.batches();
        if s.spp < k || s.spp % k != 0 {
            return Err(format!(
                "spp {} must be a multiple of the {k} independent runs per image (renderers.toml `batches`), so that the image has exactly the samples the check asks for",
                s.spp
            ));
        }
        let spp = s.spp / k;
        let dir = std::env::temp_dir().join(format!(
            "furnace-{}-{}-{}",
            self.label.replace([':', '/'], "_"),
            std::process::id(),
            self.counter.fetch_add(1, Ordering::Relaxed)
        ));
        let xml = match self.desc.exporter.as_str() {
            "mitsuba3" => export::mitsuba::write(scene, &dir).map_err(|e| e.to_string())?,
            other => return Err(format!("unknown exporter {other:?}")),
        };
        let channels = self
            .desc
            .channels
            .clone()
            .unwrap_or(["R".into(), "G".into(), "B".into()]);
        // Y of a flat spectrum: furnace's normalisation over the renderer's.
        let y_scale = Observer::Cie1931.white()[1] / native.white()[1];
        let threads = if s.threads == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            s.threads
        };
        let mut film = Film::new(s.width, s.height);
        for b in 0..k {
            let out = dir.join(format!("batch-{b}.exr"));
            // Seeds below 2^31 (Mitsuba's sampler seed is a 32-bit integer).
            let seed = crate::math::rng::mix64(s.seed ^ b) % (1 << 31);
            let value = |key: &str| -> String {
                match key {
                    "scene" => xml.display().to_string(),
                    "out" => out.display().to_string(),
                    "spp" => spp.to_string(),
                    "seed" => seed.to_string(),
                    "width" => s.width.to_string(),
                    "height" => s.height.to_string(),
                    "max_depth" => s
                        .integrator
                        .max_depth
                        .map_or("-1".into(), |d| d.to_string()),
                    "variant" => self.variant.clone(),
                    "threads" => threads.to_string(),
                    _ => String::new(),
                }
            };
            let argv: Vec<String> = self
                .desc
                .command
                .iter()
                .map(|a| {
                    let mut a = a.clone();
                    for p in PLACEHOLDERS {
                        a = a.replace(&format!("{{{p}}}"), &value(p));
                    }
                    a
                })
                .collect();
            let run = self
                .command(&argv)
                .output()
                .map_err(|e| format!("cannot run {}: {e}", argv[0]))?;
            if !run.status.success() {
                return Err(format!(
                    "{} exited with {}: {}",
                    self.label,
                    run.status,
                    tail(&String::from_utf8_lossy(&run.stderr))
                ));
            }
            let layers = io::read_exr(&out).map_err(|e| e.to_string())?;
            if (layers.width, layers.height) != (s.width, s.height) {
                return Err(format!(
                    "{} wrote {}x{}, asked {}x{}",
                    self.label, layers.width, layers.height, s.width, s.height
                ));
            }
            let plane = |c: &str| {
                layers
                    .channel(c)
                    .map(|v| v.to_vec())
                    .ok_or_else(|| format!("{} has no channel {c:?}", out.display()))
            };
            let rgb = [
                plane(&channels[0])?,
                plane(&channels[1])?,
                plane(&channels[2])?,
            ];
            for (i, px) in film.pixels.iter_mut().enumerate() {
                let native_rgb = [rgb[0][i] as f64, rgb[1][i] as f64, rgb[2][i] as f64];
                let xyz = native.rgb_to_xyz(native_rgb).map(|v| v * y_scale);
                let out_rgb = if s.observer == native {
                    native_rgb
                } else {
                    s.observer.xyz_to_rgb(xyz)
                };
                px.add(xyz, out_rgb);
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
        Ok(film)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(text: &str) -> PathBuf {
        let p = std::env::temp_dir().join(format!(
            "furnace-renderers-{}-{}.toml",
            std::process::id(),
            text.len()
        ));
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn renderer_files_are_validated_by_name() {
        let ok = "[renderer.x]\nexporter = \"mitsuba3\"\nobserver = \"mitsuba3\"\ncommand = [\"r\", \"{scene}\", \"{out}\"]\n";
        assert!(load_renderers(&write(ok)).is_ok());
        for (text, want) in [
            (
                ok.replace("{out}", "{output}"),
                "unknown placeholder {output}",
            ),
            (
                ok.replace("exporter = \"mitsuba3\"", "exporter = \"pbrt\""),
                "renderer.x.exporter: \"pbrt\"",
            ),
            (
                ok.replace("observer = \"mitsuba3\"", "observer = \"xyz\""),
                "renderer.x.observer",
            ),
            (format!("{ok}batches = 1\n"), "renderer.x.batches: 1"),
            (format!("{ok}colour = 1\n"), "unknown field `colour`"),
        ] {
            let e = load_renderers(&write(&text)).unwrap_err();
            assert!(e.contains(want), "{e}");
        }
        let r = load_renderers(&write(ok)).unwrap();
        let e = External::from_spec("y:v", &r, Path::new(".")).unwrap_err();
        assert!(
            e.contains("unknown renderer \"y\"; known: furnace, x"),
            "{e}"
        );
        let x = External::from_spec("x:fast", &r, Path::new(".")).unwrap();
        assert_eq!(
            (x.label.as_str(), x.variant.as_str(), x.batches()),
            ("x:fast", "fast", 4)
        );
    }
}
