//! External renderers described in a renderer table (`[renderer.NAME]` in TOML): images through
//! a command template fed the scene exported to the renderer's format, models through a model
//! server (`docs/model-protocol.md`). Commands run with a cleared environment (PATH, HOME, LANG,
//! TMPDIR and the table's `env`), a time limit, bounded captured output, and a temporary folder
//! removed on every way out — or, while a reproducer bundle is being gathered
//! ([`External::keep_runs_in`]), a folder kept with the exported scene and a `command.sh` that
//! re-runs the renderer. A black box's image variance comes from `batches` independent runs
//! (docs/renderers.md).

use super::renderer::{Renderer, RendererError};
use crate::export;
use crate::film::blocks::BlockFold;
use crate::film::partial::PartialFilm;
use crate::film::{merge_pixels, Film, Pixel};
use crate::integrators::Strategy;
use crate::io::image as io;
use crate::io::process;
use crate::render::RenderSettings;
use crate::scene::{Scene, Source};
use crate::spectrum::Observer;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

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
    /// The sample pattern within a pixel (default `independent`; `stratified`, `sobol`, or any
    /// other name such as `tabulated-sobol`): a convergence check that states one pattern's
    /// rate judges only renderers that sample with it.
    #[serde(default)]
    pub sampler: Option<String>,
    /// Its colour pipeline: `spectral` (the default; for Mitsuba, variants named `*_rgb` are
    /// `rgb`) or `rgb`. An RGB renderer multiplies RGB projections where a spectral one
    /// multiplies spectra, so scenes with coloured BSDFs or media are refused (SKIPPED with
    /// the reason) rather than judged against spectral closed forms.
    #[serde(default)]
    pub colour: Option<String>,
    /// How the samples per pixel it renders relate to the `{spp}` it is given: `exact` (the
    /// default) or `at-least`, for a renderer that stops only at a periodic check after the
    /// count is reached (LuxCore's `batch.haltspp`: 1165–1292 samples for a nominal 4 on an
    /// 8×8 image). A convergence ladder's N is then not N, so convergence checks are SKIPPED
    /// with the reason; region tests stay valid (their standard error comes from the batches).
    #[serde(default)]
    pub spp: Option<String>,
    /// A command that succeeds when the renderer is installed.
    #[serde(default)]
    pub probe: Option<Vec<String>>,
    /// Environment variables set for the probe, the command and the model server (a variable
    /// already set in furnace's environment wins, so a user can override without editing the
    /// file); the rest of the environment is cleared but for PATH, HOME, LANG and TMPDIR.
    #[serde(default)]
    pub env: BTreeMap<String, String>,
    /// The image command's argv template; placeholders {scene} {out} {spp} {seed} {width}
    /// {height} {max_depth} {variant} {threads} {furnace}. Without it the renderer serves
    /// models only.
    #[serde(default)]
    pub command: Option<Vec<String>>,
    /// The model server's argv template ({variant}, {furnace}); without it the renderer
    /// serves images only.
    #[serde(default)]
    pub models: Option<Vec<String>>,
    /// Longest run of the image command or the probe, seconds (default 600).
    #[serde(default)]
    pub timeout: Option<f64>,
    /// Longest wait for one model-server reply, seconds (default 60).
    #[serde(default)]
    pub model_timeout: Option<f64>,
    /// A command ({variant}, {furnace}) that prints the renderer's version, recorded in
    /// reproducer bundles.
    #[serde(default)]
    pub version: Option<Vec<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderersFile {
    #[serde(default)]
    renderer: BTreeMap<String, RendererDesc>,
}

/// Placeholders a command template may use.
pub const PLACEHOLDERS: [&str; 10] = [
    "scene",
    "out",
    "spp",
    "seed",
    "width",
    "height",
    "max_depth",
    "variant",
    "threads",
    "furnace",
];

/// Temporary folders made so far by this process (their names' last part).
static TEMPORARY: AtomicU64 = AtomicU64::new(0);

/// Bytes of a command's stdout and stderr kept (the rest is read and dropped).
const OUTPUT_KEPT: usize = 64 * 1024;

/// Reads a renderers file; errors give file:line:column or name the renderer and key.
pub fn load_renderers(path: &Path) -> Result<BTreeMap<String, RendererDesc>, String> {
    let text = crate::io::read_text(path, "the renderers file").map_err(|e| e.to_string())?;
    parse_renderers(&text, path)
}

/// The renderer table built into furnace (its `renderers.toml` at build time): Mitsuba 3 and
/// furnace's own models served through the protocol.
pub const BUILT_IN: &str = include_str!("../../renderers.toml");

/// Parses a renderers table (`path` names it in errors).
pub fn parse_renderers(text: &str, path: &Path) -> Result<BTreeMap<String, RendererDesc>, String> {
    let f: RenderersFile =
        crate::io::parse_toml(&Source { path, text }).map_err(|e| e.to_string())?;
    for (name, d) in &f.renderer {
        let at = |k: &str, m: String| format!("{}: renderer.{name}.{k}: {m}", path.display());
        if d.exporter != "mitsuba3" && d.exporter != "json" {
            return Err(at(
                "exporter",
                format!("{:?}; allowed: \"mitsuba3\", \"json\"", d.exporter),
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
        if d.sampler
            .as_ref()
            .is_some_and(|x| x.is_empty() || x.chars().any(char::is_whitespace))
        {
            return Err(at(
                "sampler",
                "give the pattern's name, one word such as \"independent\" or \"tabulated-sobol\""
                    .into(),
            ));
        }
        if d.colour
            .as_ref()
            .is_some_and(|c| c != "rgb" && c != "spectral")
        {
            return Err(at(
                "colour",
                format!(
                    "{:?}; allowed: \"spectral\", \"rgb\"",
                    d.colour.as_deref().unwrap_or("")
                ),
            ));
        }
        if d.spp
            .as_ref()
            .is_some_and(|x| x != "exact" && x != "at-least")
        {
            return Err(at(
                "spp",
                format!(
                    "{:?}; allowed: \"exact\", \"at-least\"",
                    d.spp.as_deref().unwrap_or("")
                ),
            ));
        }
        if d.command.is_none() && d.models.is_none() {
            return Err(at(
                "command",
                "missing; give `command` (images), `models` (a model server) or both".into(),
            ));
        }
        for (key, limit) in [("timeout", d.timeout), ("model_timeout", d.model_timeout)] {
            if let Some(t) = limit.filter(|t| !(t.is_finite() && *t > 0.0 && *t <= 86_400.0)) {
                return Err(at(key, format!("{t:?}: give seconds in (0, 86400]")));
            }
        }
        if let Some(c) = &d.channels {
            // one channel three times is a grey renderer's; two of one and a third a slip
            let all_one = c[0] == c[1] && c[1] == c[2];
            let distinct = c[0] != c[1] && c[1] != c[2] && c[0] != c[2];
            if c.iter().any(String::is_empty) || !(all_one || distinct) {
                return Err(at(
                    "channels",
                    format!(
                        "{c:?}: give three distinct channels (R, G, B), or one three times for a grey renderer"
                    ),
                ));
            }
        }
        for (key, argv) in [("command", &d.command), ("models", &d.models)] {
            let Some(argv) = argv else { continue };
            if argv.is_empty() {
                return Err(at(key, "empty; give the argv template".into()));
            }
            for arg in argv {
                let mut rest = arg.as_str();
                while let Some(i) = rest.find('{') {
                    let j = rest[i..]
                        .find('}')
                        .map(|j| i + j)
                        .ok_or_else(|| at(key, format!("{arg:?} has an unclosed '{{'")))?;
                    let p = &rest[i + 1..j];
                    if !PLACEHOLDERS.contains(&p) {
                        return Err(at(
                            key,
                            format!(
                                "unknown placeholder {{{p}}} in {arg:?}; allowed: {}",
                                PLACEHOLDERS.map(|p| format!("{{{p}}}")).join(" ")
                            ),
                        ));
                    }
                    rest = &rest[j + 1..];
                }
            }
        }
        // the image command must be told where to write: its EXR is read from {out}
        if let Some(argv) = &d.command {
            if !argv.iter().any(|a| a.contains("{out}")) {
                return Err(at(
                    "command",
                    "has no {out}: furnace reads the image the command writes there".into(),
                ));
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
    /// Where the runs of the check under way are kept (exported scene, command.sh, images),
    /// when a reproducer bundle is being gathered.
    keep: Mutex<Option<PathBuf>>,
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
        if variant.as_ref().is_some_and(String::is_empty) {
            return Err(format!(
                "--renderer {spec:?}: the variant after ':' is empty; give NAME or NAME:VARIANT"
            ));
        }
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
            keep: Mutex::new(None),
        })
    }

    /// Runs the probe; Err(message) when the renderer is not available, ending with the
    /// table's description (which says how to install it) and where the README sets it up.
    pub fn probe(&self) -> Result<(), String> {
        let Some(p) = &self.desc.probe else {
            return Ok(());
        };
        let p = self.expand(p, &|_| None);
        let help = match &self.desc.description {
            Some(d) => format!(" [the table's entry: {d}; setting up a renderer: README, \"Judging another renderer\"]"),
            None => " [setting up a renderer: README, \"Judging another renderer\"]".into(),
        };
        let out = run_bounded(self.command(&p), self.timeout())
            .map_err(|e| format!("{:?}: {e}{help}", p.join(" ")))?;
        if out.success {
            Ok(())
        } else {
            Err(format!(
                "{:?} failed ({}): {}{help}",
                p.join(" "),
                out.status,
                said(&out)
            ))
        }
    }

    /// The environment of its commands: the table's `env` (unless furnace's own environment
    /// sets the variable), on top of PATH, HOME, LANG and TMPDIR.
    pub fn environment(&self) -> Vec<(String, String)> {
        self.desc
            .env
            .iter()
            .map(|(k, v)| {
                let v = std::env::var(k).unwrap_or_else(|_| v.clone());
                (k.clone(), v)
            })
            .collect()
    }

    /// A process for `argv` in the working directory with the renderer's environment.
    fn command(&self, argv: &[String]) -> Command {
        let mut c = Command::new(&argv[0]);
        c.args(&argv[1..]).current_dir(&self.workdir).env_clear();
        for k in ["PATH", "HOME", "LANG", "TMPDIR"] {
            if let Some(v) = std::env::var_os(k) {
                c.env(k, v);
            }
        }
        for (k, v) in self.environment() {
            c.env(k, v);
        }
        c
    }

    /// Longest run of a command.
    pub fn timeout(&self) -> Duration {
        Duration::from_secs_f64(self.desc.timeout.unwrap_or(600.0))
    }

    /// `argv` with its placeholders replaced ({variant} and {furnace} always, the rest by `value`).
    fn expand(&self, argv: &[String], value: &dyn Fn(&str) -> Option<String>) -> Vec<String> {
        let furnace = std::env::current_exe()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|_| "furnace".into());
        argv.iter()
            .map(|a| {
                let mut a = a.clone();
                for p in PLACEHOLDERS {
                    let v = match p {
                        "variant" => Some(self.variant.clone()),
                        "furnace" => Some(furnace.clone()),
                        _ => value(p),
                    };
                    if let Some(v) = v {
                        a = a.replace(&format!("{{{p}}}"), &v);
                    }
                }
                a
            })
            .collect()
    }

    /// How to start its model server, when it has one.
    pub fn model_server(&self) -> Option<super::under_test::ServerCommand> {
        let argv = self.desc.models.as_ref()?;
        Some(super::under_test::ServerCommand {
            argv: self.expand(argv, &|_| None),
            workdir: self.workdir.clone(),
            env: self.environment(),
            timeout: Duration::from_secs_f64(self.desc.model_timeout.unwrap_or(60.0)),
        })
    }

    /// Keep every later render's exported scene, images and `command.sh` in a folder
    /// `render-N` under `dir` (None: temporary folders again, removed after each render).
    pub fn keep_runs_in(&self, dir: Option<PathBuf>) {
        *self.keep.lock().unwrap_or_else(|e| e.into_inner()) = dir;
    }

    /// The renderer's version from the table's `version` command (its first line of output),
    /// or why there is none.
    pub fn version(&self) -> String {
        let Some(v) = &self.desc.version else {
            return "not recorded (the renderer table has no `version` command)".into();
        };
        let argv = self.expand(v, &|_| None);
        match run_bounded(self.command(&argv), self.timeout()) {
            Ok(out) if out.success => out.stdout.lines().next().unwrap_or("").trim().to_string(),
            Ok(out) => format!(
                "{:?} failed ({}): {}",
                argv.join(" "),
                out.status,
                said(&out)
            ),
            Err(e) => format!("{:?}: {e}", argv.join(" ")),
        }
    }

    /// A shell script line running `argv` with the renderer's environment, every path under
    /// `dir` written relative to the script's own folder (`$here`).
    fn script_line(&self, argv: &[String], dir: &Path) -> String {
        let prefix = dir.display().to_string();
        let env: Vec<String> = self
            .environment()
            .iter()
            .map(|(k, v)| format!("{k}={}", shell_quote(v)))
            .collect();
        let args: Vec<String> = argv
            .iter()
            .map(|a| match a.strip_prefix(&prefix) {
                Some(rest) => format!("\"$here\"{}", shell_quote(rest)),
                None => shell_quote(a),
            })
            .collect();
        // furnace runs the renderer with a cleared environment: so does the script
        let env = format!(
            "env -i PATH=\"$PATH\" HOME=\"$HOME\" LANG=\"$LANG\" TMPDIR=\"$TMPDIR\" {}",
            env.iter().map(|e| format!("{e} ")).collect::<String>()
        );
        format!("{env}{}\n", args.join(" "))
    }

    /// Independent runs per image.
    pub fn batches(&self) -> u64 {
        self.desc.batches.unwrap_or(4) as u64
    }
}

/// `s` quoted for a POSIX shell: as is when it holds only safe characters, else in single
/// quotes with each ' written '\''.
pub fn shell_quote(s: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c);
    if !s.is_empty() && s.chars().all(safe) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// What a failed run said: its stderr's last lines, else its stdout's, else that it printed
/// nothing (a message ending in a bare colon said nothing).
fn said(out: &RunOutput) -> String {
    match (tail(&out.stderr), tail(&out.stdout)) {
        (e, _) if !e.is_empty() => e,
        (_, o) if !o.is_empty() => format!("(nothing on stderr) stdout: {o}"),
        _ => "it printed nothing on stdout or stderr".into(),
    }
}

fn tail(s: &str) -> String {
    let lines: Vec<&str> = s.lines().rev().take(3).collect();
    let t = lines.into_iter().rev().collect::<Vec<_>>().join(" | ");
    let cut: String = t.chars().take(600).collect();
    if cut.len() < t.len() {
        format!("{cut}…")
    } else {
        cut
    }
}

/// What a bounded run printed and how it ended.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// It exited with status 0.
    pub success: bool,
    /// Its exit status, for messages.
    pub status: String,
    /// Its exit code (None: ended by a signal).
    pub status_code: Option<i32>,
    /// The last `OUTPUT_KEPT` (64 KiB) bytes of its stderr (lossy UTF-8).
    pub stderr: String,
    /// The last `OUTPUT_KEPT` (64 KiB) bytes of its stdout (lossy UTF-8).
    pub stdout: String,
}

/// Runs `cmd` with stdin closed, stdout and stderr read to their ends but only their last
/// `OUTPUT_KEPT` (64 KiB) bytes kept, and killed after `timeout`. It runs in a process group of
/// its own ([`crate::io::process`]): when it exits, what it left running in the background is
/// killed too, so that no leftover holds its output open and makes the run wait; a process
/// that left the group and holds the output is waited for until `timeout` at most.
pub fn run_bounded(mut cmd: Command, timeout: Duration) -> Result<RunOutput, String> {
    let start = Instant::now();
    let mut group = process::spawn(
        cmd.stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    )
    .map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    let (done_tx, done) = std::sync::mpsc::channel::<()>();
    let keep = |r: Option<Box<dyn Read + Send>>| {
        let kept = std::sync::Arc::new(Mutex::new(Vec::<u8>::new()));
        let sink = std::sync::Arc::clone(&kept);
        let done_tx = done_tx.clone();
        std::thread::spawn(move || {
            if let Some(mut r) = r {
                let mut buf = [0u8; 8192];
                while let Ok(n) = r.read(&mut buf) {
                    if n == 0 {
                        break;
                    }
                    let mut k = sink.lock().unwrap_or_else(|e| e.into_inner());
                    k.extend_from_slice(&buf[..n]);
                    if k.len() > 2 * OUTPUT_KEPT {
                        let excess = k.len() - OUTPUT_KEPT;
                        k.drain(..excess);
                    }
                }
            }
            let _ = done_tx.send(());
        });
        kept
    };
    let out = keep(
        group
            .child
            .stdout
            .take()
            .map(|r| Box::new(r) as Box<dyn Read + Send>),
    );
    let err = keep(
        group
            .child
            .stderr
            .take()
            .map(|r| Box::new(r) as Box<dyn Read + Send>),
    );
    drop(done_tx);
    let killed = || {
        format!(
            "did not finish within {:.0} s (renderers table `timeout`); killed with what it started",
            timeout.as_secs_f64()
        )
    };
    loop {
        match group.exited() {
            Ok(true) => break,
            Ok(false) if start.elapsed() > timeout => {
                let _ = group.kill_and_wait();
                return Err(killed());
            }
            Ok(false) => std::thread::sleep(Duration::from_millis(20)),
            Err(e) => {
                let _ = group.kill_and_wait();
                return Err(format!("cannot wait for the process: {e}"));
            }
        }
    }
    let status = group
        .kill_and_wait()
        .map_err(|e| format!("cannot wait for the process: {e}"))?;
    // both readers end once every holder of the pipes has ended (the killed group's members
    // within moments: a second at least, even at the timeout)
    for _ in 0..2 {
        let left = timeout
            .saturating_sub(start.elapsed())
            .max(Duration::from_secs(1));
        if done.recv_timeout(left).is_err() {
            return Err(format!(
                "exited ({status}) but a process it started outside its process group still held its output open after {:.0} s (renderers table `timeout`)",
                timeout.as_secs_f64()
            ));
        }
    }
    let text = |k: &Mutex<Vec<u8>>| {
        let k = k.lock().unwrap_or_else(|e| e.into_inner());
        let excess = k.len().saturating_sub(OUTPUT_KEPT);
        String::from_utf8_lossy(&k[excess..]).into_owned()
    };
    Ok(RunOutput {
        success: status.success(),
        status: status.to_string(),
        status_code: status.code(),
        stderr: text(&err),
        stdout: text(&out),
    })
}

impl Renderer for External {
    fn name(&self) -> String {
        self.label.clone()
    }

    fn is_reference(&self) -> bool {
        false
    }

    fn renders_images(&self) -> bool {
        self.desc.command.is_some()
    }

    /// Its images are read from 32-bit float EXRs and accumulated by renderers in float32:
    /// an exact estimator (a point light through a pixel, next-event estimation inside a
    /// sphere) reads 1e-7 to 1e-6 off its closed form in Cycles and LuxCore (f32 unit
    /// roundoff 6e-8, summed over samples), so a region test allows the float32 rounding of
    /// the model checks, 1e-5 (`Precision::F32`).
    fn image_rounding(&self) -> f64 {
        super::under_test::Precision::F32.rounding()
    }

    fn render(&self, scene: &Scene, s: &RenderSettings) -> Result<Film, RendererError> {
        let kept = self
            .keep
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some();
        self.render_batches(scene, s).map_err(|e| {
            // a file named in the message is gone by the time it is read, unless kept
            let temporary = std::env::temp_dir().join("furnace-");
            if !kept && e.contains(&*temporary.to_string_lossy()) {
                RendererError(format!(
                    "{e} [the files named were temporary and are removed with the run; --report or --bundles keeps a failing check's renders]"
                ))
            } else {
                RendererError(e)
            }
        })
    }

    fn sampler(&self) -> String {
        self.desc
            .sampler
            .clone()
            .unwrap_or_else(|| "independent".into())
    }

    fn exact_spp(&self) -> bool {
        self.desc.spp.as_deref() != Some("at-least")
    }

    fn spp_step(&self) -> u64 {
        self.batches()
    }
}

impl External {
    /// Whether it renders in RGB (`colour = "rgb"`, or a Mitsuba variant named `*_rgb`).
    pub fn renders_rgb(&self) -> bool {
        match self.desc.colour.as_deref() {
            Some(c) => c == "rgb",
            None => self.variant.ends_with("_rgb"),
        }
    }

    /// Renders the image as `batches` independent runs of the command.
    fn render_batches(&self, scene: &Scene, s: &RenderSettings) -> Result<Film, String> {
        let fold = self.render_batch_range(scene, s, 0..self.batches())?;
        let pixels = fold
            .finish(&|a: &mut Vec<Pixel>, b: &Vec<Pixel>| merge_pixels(a, b))
            .ok_or_else(|| format!("{}: no batch ran", self.label))?;
        Ok(Film {
            width: s.width,
            height: s.height,
            pixels,
            truncated_paths: 0,
        })
    }

    /// Renders batches `batches` (of [`External::batches`]) of the image: one part of a
    /// sharded reference render, each batch a block of the merge tree of film::blocks, so that
    /// the parts merge (film::partial) to the film of all batches bit for bit. Each pixel
    /// holds one value per batch (its count is the batch count). The header's attributes are
    /// left empty for the caller.
    pub fn render_part(
        &self,
        scene: &Scene,
        s: &RenderSettings,
        batches: std::ops::Range<u64>,
    ) -> Result<PartialFilm, String> {
        let total = self.batches();
        if !(batches.start < batches.end && batches.end <= total) {
            return Err(format!(
                "batches {}..{} are not a non-empty part of {}'s {total} runs per image",
                batches.start, batches.end, self.label
            ));
        }
        let pieces = self.render_batch_range(scene, s, batches)?.into_pieces();
        Ok(PartialFilm::new(
            (s.width, s.height),
            total,
            pieces,
            |span| span.end() - span.start,
            0,
            crate::render::scene_fingerprint(scene),
        ))
    }

    /// Runs the command for each batch in `batches`, folding the batch images in order.
    fn render_batch_range(
        &self,
        scene: &Scene,
        s: &RenderSettings,
        batches: std::ops::Range<u64>,
    ) -> Result<BlockFold<Vec<Pixel>>, String> {
        if s.integrator.strategy != Strategy::Mis {
            return Err(format!(
                "{} runs its own estimator; checks that select BSDF-only or light-only sampling do not apply",
                self.label
            ));
        }
        if self.renders_rgb() && !scene.scatters_grey() {
            return Err(format!(
                "{}{} renders in RGB: this scene's BSDFs or media vary with wavelength, and a product of RGB projections is not the projection of the spectral product (Cycles, LuxCore and Mitsuba's own scalar_rgb all read the Cornell box's red wall in blue +580 to +610 % against the spectral reference; reports/renderers/four/FINDINGS.md)",
                super::renderer::UNSUPPORTED,
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
        if s.spp < k || !s.spp.is_multiple_of(k) {
            return Err(format!(
                "spp {} must be a multiple of the {k} independent runs per image (renderers.toml `batches`), so that the image has exactly the samples the check asks for",
                s.spp
            ));
        }
        let spp = s.spp / k;
        let Some(command) = &self.desc.command else {
            return Err(format!("{} serves models only (no `command`)", self.label));
        };
        let n = self.counter.fetch_add(1, Ordering::Relaxed);
        let kept = self
            .keep
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            .map(|root| root.join(format!("render-{n}")));
        // a kept folder outlives the process; a temporary one is removed on every way out
        let (dir, _temporary) = match &kept {
            Some(d) => (d.clone(), None),
            None => {
                let d = std::env::temp_dir().join(format!(
                    "furnace-{}-{}-{}",
                    self.label.replace([':', '/'], "_"),
                    std::process::id(),
                    // unique in the process: two renderers of one name may render at once
                    TEMPORARY.fetch_add(1, Ordering::Relaxed)
                ));
                (d.clone(), Some(crate::io::cleanup::Pending::new(d)))
            }
        };
        let dir = dir.as_path();
        let mut script = kept.as_ref().map(|_| {
            format!(
                "#!/bin/sh\n# {} as furnace ran it: {} independent runs of {} spp, {}x{} px; each writes batch-B.exr here.\nhere=$(cd \"$(dirname \"$0\")\" && pwd)\ncd {} || exit 1\n",
                // a comment line: no control character may end it early
                self.label.replace(char::is_control, "?"),
                k,
                spp,
                s.width,
                s.height,
                shell_quote(&self.workdir.canonicalize().unwrap_or(self.workdir.clone()).display().to_string())
            )
        });
        let exported = match self.desc.exporter.as_str() {
            "mitsuba3" => export::mitsuba::write(scene, dir),
            "json" => export::json::write(scene, dir),
            other => return Err(format!("unknown exporter {other:?}")),
        };
        let xml = exported.map_err(|e| match e {
            export::ExportError::Unsupported { .. } => {
                format!("{}{e}", super::renderer::UNSUPPORTED)
            }
            e => e.to_string(),
        })?;
        let channels = self
            .desc
            .channels
            .clone()
            .unwrap_or(["R".into(), "G".into(), "B".into()]);
        let threads = if s.threads == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            s.threads
        };
        let pipelines = Pipelines::new(&native, &s.observer);
        let mut fold = BlockFold::new(batches.start);
        for b in batches {
            let out = dir.join(format!("batch-{b}.exr"));
            let seed = batch_seed(s.seed, b);
            let value = |key: &str| -> Option<String> {
                Some(match key {
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
                    "threads" => threads.to_string(),
                    _ => return None,
                })
            };
            let argv = self.expand(command, &value);
            if let Some(script) = &mut script {
                script.push_str(&self.script_line(&argv, dir));
                let path = dir.join("command.sh");
                std::fs::write(&path, script.as_bytes())
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            }
            // the table's time limit, or what is left of the check's, whichever is shorter
            let left = s
                .deadline
                .map(|d| d.saturating_duration_since(Instant::now()));
            let limit = left.map_or(self.timeout(), |l| l.min(self.timeout()));
            let run = run_bounded(self.command(&argv), limit)
                .map_err(|e| format!("{}: {e}", self.label))?;
            // the scene-JSON drivers refuse what their renderer cannot express: exit 3 and a
            // line starting `unsupported:` on stderr (docs/scene-json.md)
            if run.status_code == Some(3) {
                if let Some(line) = run.stderr.lines().find(|l| l.starts_with("unsupported:")) {
                    return Err(format!(
                        "{}{}",
                        super::renderer::UNSUPPORTED,
                        line.trim_start_matches("unsupported:").trim()
                    ));
                }
            }
            if !run.success {
                return Err(format!(
                    "{} exited with {}: {}",
                    self.label,
                    run.status,
                    said(&run)
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
            // a NaN or infinite pixel is a finding about the renderer, and no statistic can
            // be formed from it: the render ends here, naming it
            let bad = (0..s.width * s.height).filter(|&i| rgb.iter().any(|c| !c[i].is_finite()));
            if let Some(first) = bad.clone().next() {
                return Err(format!(
                    "{} wrote {} pixels whose {} is NaN or infinite in {} (the first at x = {}, y = {}): no statistic can be formed from them; a NaN or infinite radiance is itself a finding about the renderer",
                    self.label,
                    bad.count(),
                    channels.join("/"),
                    out.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned()),
                    first % s.width,
                    first / s.width
                ));
            }
            let mut batch = vec![Pixel::default(); s.width * s.height];
            for (i, px) in batch.iter_mut().enumerate() {
                let native_rgb = [rgb[0][i] as f64, rgb[1][i] as f64, rgb[2][i] as f64];
                let (xyz, out_rgb) = pipelines.convert(native_rgb);
                px.add(xyz, out_rgb);
            }
            fold.push(batch, &|a: &mut Vec<Pixel>, b: &Vec<Pixel>| {
                merge_pixels(a, b)
            });
        }
        Ok(fold)
    }
}

/// Carries a renderer's linear RGB from its own colour pipeline into furnace's XYZ and the
/// check's RGB. Each pipeline normalises a flat spectrum of 1 its own way (Mitsuba's Y of it is
/// 1.00100, furnace's 1), so XYZ is scaled channel by channel by the ratio of the two
/// pipelines' whites: exact for grey scenes, the only ones RGB renderers are judged on (without
/// it, Cycles and LuxCore read Mitsuba's grey furnace box 0.05–0.1 % low).
#[derive(Debug, Clone)]
pub struct Pipelines {
    native: Observer,
    check: Observer,
    to_furnace: [f64; 3],
    to_check: [f64; 3],
}

impl Pipelines {
    /// From the renderer's pipeline `native` to furnace's units and the check's `check`.
    pub fn new(native: &Observer, check: &Observer) -> Pipelines {
        let (own, furnace, theirs) = (native.white(), Observer::Cie1931.white(), check.white());
        Pipelines {
            native: native.clone(),
            check: check.clone(),
            to_furnace: std::array::from_fn(|k| furnace[k] / own[k]),
            to_check: std::array::from_fn(|k| theirs[k] / own[k]),
        }
    }

    /// (XYZ in furnace's units, RGB in the check's pipeline) of the renderer's `native_rgb`.
    pub fn convert(&self, native_rgb: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let xyz = self.native.rgb_to_xyz(native_rgb);
        let out_rgb = if self.check == self.native {
            native_rgb
        } else {
            self.check
                .xyz_to_rgb(std::array::from_fn(|k| xyz[k] * self.to_check[k]))
        };
        (
            std::array::from_fn(|k| xyz[k] * self.to_furnace[k]),
            out_rgb,
        )
    }
}

/// The seed of batch `b` of a render with seed `seed`, below 2^31 (Mitsuba's sampler seed is
/// a 32-bit integer). Through `run_seed`: mix64(seed ^ b) gave seeds 0 to 3 the same four
/// batches in another order, so their images were the same.
fn batch_seed(seed: u64, b: u64) -> u64 {
    crate::math::rng::run_seed(seed, b, 0x4241_5443) % (1 << 31) // "BATC"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_with_different_seeds_share_no_batch() {
        let mut seen = std::collections::HashSet::new();
        for seed in 0..16 {
            for b in 0..16 {
                assert!(seen.insert(batch_seed(seed, b)), "seed {seed} batch {b}");
            }
        }
    }

    /// A renderer that writes furnace's film RGB of a flat spectrum (as the JSON exporter gives
    /// Cycles and LuxCore) reads, in Mitsuba's pipeline, what Mitsuba's film gives a flat
    /// spectrum; in furnace's own units its Y is 1.
    #[test]
    fn a_grey_pixel_reads_the_same_in_every_pipeline() {
        let white = Observer::Cie1931.xyz_to_rgb(Observer::Cie1931.white());
        let (xyz, rgb) = Pipelines::new(&Observer::Cie1931, &Observer::Mitsuba3).convert(white);
        let want = Observer::Mitsuba3.xyz_to_rgb(Observer::Mitsuba3.white());
        for k in 0..3 {
            assert!((rgb[k] - want[k]).abs() < 1e-12, "{rgb:?} vs {want:?}");
            assert!((xyz[k] - Observer::Cie1931.white()[k]).abs() < 1e-12);
        }
        // and back: Mitsuba's RGB of a flat spectrum is furnace's Y = 1
        let (xyz, rgb) = Pipelines::new(&Observer::Mitsuba3, &Observer::Mitsuba3).convert(want);
        assert_eq!(rgb, want);
        assert!((xyz[1] - 1.0).abs() < 1e-12, "{xyz:?}");
        // the old conversion (XYZ in furnace's units straight into Mitsuba's matrix) is 0.1 % low
        let old = Observer::Mitsuba3.xyz_to_rgb(Observer::Cie1931.white());
        assert!((old[1] / want[1] - 1.0).abs() > 5e-4, "{old:?} {want:?}");
    }

    #[test]
    fn shell_words_survive_quotes_and_spaces() {
        assert_eq!(shell_quote("a/b.toml"), "a/b.toml");
        assert_eq!(shell_quote("x[a=0.5]"), "'x[a=0.5]'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
        assert_eq!(shell_quote(""), "''");
    }

    /// A renderer table written to a temporary file, removed when dropped.
    struct Written(PathBuf);

    impl Drop for Written {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    impl std::ops::Deref for Written {
        type Target = std::path::Path;
        fn deref(&self) -> &std::path::Path {
            &self.0
        }
    }

    fn write(text: &str) -> Written {
        let p = std::env::temp_dir().join(format!(
            "furnace-renderers-{}-{}.toml",
            std::process::id(),
            text.len()
        ));
        std::fs::write(&p, text).unwrap();
        Written(p)
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
            (format!("{ok}gamma = 1\n"), "unknown field `gamma`"),
            (
                format!("{ok}timeout = 0\n"),
                "renderer.x.timeout: 0.0: give seconds",
            ),
            (
                format!("{ok}channels = [\"R\", \"R\", \"B\"]\n"),
                "give three distinct channels",
            ),
            (ok.replace(", \"{out}\"", ""), "has no {out}"),
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
        let e = External::from_spec("x:", &r, Path::new(".")).unwrap_err();
        assert!(e.contains("variant after ':' is empty"), "{e}");
        let x = External::from_spec("x:fast", &r, Path::new(".")).unwrap();
        assert_eq!(
            (x.label.as_str(), x.variant.as_str(), x.batches()),
            ("x:fast", "fast", 4)
        );
    }
}
