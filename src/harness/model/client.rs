//! The model protocol's client: starts a model server, reads its hello, and turns its models
//! into the batched interface of `under_test.rs`. Every reply is checked (shape, NaN and ±∞, timeout);
//! a failure names the op and model and quotes the server's stderr tail.

use super::protocol::{self, preview, read_message, write_message, Message, Op};
use crate::harness::under_test::{
    BsdfFlags, BsdfModel, EmitterModel, EmitterSample, ModelError, ModelSource, Named, PhaseModel,
    Precision, ServerCommand,
};
use crate::io::process;
use crate::math::Vec3;
use crate::media::PhaseSample;
use crate::scattering::BsdfSample;
use crate::spectrum::{SampledSpectrum, Wavelengths};
use serde_json::{json, Value};
use std::collections::VecDeque;
use std::io::{BufReader, Read, Write};
use std::process::{ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Bytes of the server's stderr kept for error messages.
const STDERR_KEPT: usize = 4096;

struct Connection {
    /// The server, in a process group of its own (killed with what it started).
    server: process::Group,
    /// Messages for the writer thread, which owns the server's stdin (a server that stops
    /// reading blocks that thread, never the caller, who times out waiting for the reply).
    stdin: Option<std::sync::mpsc::Sender<Vec<u8>>>,
    replies: Receiver<Result<Message, String>>,
    stderr: Arc<Mutex<VecDeque<u8>>>,
    dead: Option<String>,
    timeout: Duration,
}

impl Connection {
    fn stderr_tail(&self) -> String {
        let bytes: Vec<u8> = self
            .stderr
            .lock()
            .map(|b| b.iter().copied().collect())
            .unwrap_or_default();
        let text = String::from_utf8_lossy(&bytes);
        let lines: Vec<&str> = text.lines().rev().take(5).collect();
        let tail = lines.into_iter().rev().collect::<Vec<_>>().join(" | ");
        if tail.is_empty() {
            "(no stderr)".into()
        } else {
            format!("stderr: {tail}")
        }
    }

    /// Ends the connection with `why` (the server is killed) and returns the error.
    fn fail(&mut self, why: String) -> ModelError {
        let _ = self.server.kill_and_wait();
        self.stdin = None;
        // give the stderr reader a moment to collect the last lines
        std::thread::sleep(Duration::from_millis(50));
        let msg = format!("model server: {why}; {}", self.stderr_tail());
        self.dead = Some(msg.clone());
        ModelError(msg)
    }

    /// Sends one message and waits for the reply.
    fn call(
        &mut self,
        header: Value,
        width: usize,
        payload: &[f64],
    ) -> Result<Message, ModelError> {
        if let Some(d) = &self.dead {
            return Err(ModelError(d.clone()));
        }
        let what = header
            .get("op")
            .and_then(Value::as_str)
            .unwrap_or("?")
            .to_string();
        let mut bytes = Vec::with_capacity(payload.len() * 8 + 256);
        let sent = write_message(&mut bytes, header, width, payload).and_then(|_| {
            match self.stdin.as_ref() {
                Some(tx) => tx
                    .send(bytes)
                    .map_err(|_| std::io::Error::other("the server's stdin is closed")),
                None => Err(std::io::Error::other("stdin closed")),
            }
        });
        if let Err(e) = sent {
            std::thread::sleep(Duration::from_millis(50));
            let why = match self.server.exited() {
                Ok(true) => {
                    let status = self.server.kill_and_wait().map(|s| s.to_string());
                    format!(
                        "exited ({}) before answering {what}",
                        status.unwrap_or_default()
                    )
                }
                _ => format!("cannot send {what}: {e}"),
            };
            return Err(self.fail(why));
        }
        match self.replies.recv_timeout(self.timeout) {
            Ok(Ok(m)) => Ok(m),
            Ok(Err(e)) => Err(self.fail(format!("bad reply to {what}: {e}"))),
            Err(RecvTimeoutError::Timeout) => Err(self.fail(format!(
                "no reply to {what} within {:.0} s (model_timeout)",
                self.timeout.as_secs_f64()
            ))),
            Err(RecvTimeoutError::Disconnected) => {
                // its output closed: it has ended, or will at the kill
                let status = self
                    .server
                    .kill_and_wait()
                    .map(|s| s.to_string())
                    .unwrap_or_default();
                Err(self.fail(format!("exited ({status}) before answering {what}")))
            }
        }
    }
}

impl Drop for Connection {
    fn drop(&mut self) {
        if let Some(tx) = self.stdin.take() {
            let mut bye = Vec::new();
            let _ = write_message(&mut bye, json!({"op": "bye"}), 0, &[]);
            let _ = tx.send(bye);
        }
        // a server that does not end on bye/end of input within a second is killed; what it
        // started is killed either way (process::Group's drop)
        for _ in 0..20 {
            if matches!(self.server.exited(), Ok(true)) {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// A running model server and the models it serves.
pub struct RemoteModels {
    conn: Arc<Mutex<Connection>>,
    describe: String,
    precision: Precision,
    bsdfs: Vec<Named<dyn BsdfModel>>,
    phases: Vec<Named<dyn PhaseModel>>,
    emitters: Vec<Named<dyn EmitterModel>>,
}

impl RemoteModels {
    /// Starts the server and reads its hello.
    pub fn start(cmd: &ServerCommand) -> Result<RemoteModels, ModelError> {
        let program = cmd
            .argv
            .first()
            .ok_or_else(|| ModelError("empty model server command".into()))?;
        let mut c = Command::new(program);
        c.args(&cmd.argv[1..])
            .current_dir(&cmd.workdir)
            .env_clear()
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        for k in ["PATH", "HOME", "LANG", "TMPDIR"] {
            if let Some(v) = std::env::var_os(k) {
                c.env(k, v);
            }
        }
        for (k, v) in &cmd.env {
            c.env(k, v);
        }
        let mut server = process::spawn(&mut c)
            .map_err(|e| ModelError(format!("cannot start model server {program:?}: {e}")))?;
        let stdin = server.child.stdin.take().map(|mut w: ChildStdin| {
            let (tx, rx) = std::sync::mpsc::channel::<Vec<u8>>();
            std::thread::spawn(move || {
                for bytes in rx {
                    if w.write_all(&bytes).and_then(|_| w.flush()).is_err() {
                        break;
                    }
                }
            });
            tx
        });
        let stdout = server.child.stdout.take().expect("piped");
        let stderr_pipe = server.child.stderr.take().expect("piped");
        let stderr = Arc::new(Mutex::new(VecDeque::new()));
        let sink = Arc::clone(&stderr);
        std::thread::spawn(move || {
            let mut r = stderr_pipe;
            let mut buf = [0u8; 4096];
            while let Ok(n) = r.read(&mut buf) {
                if n == 0 {
                    break;
                }
                if let Ok(mut b) = sink.lock() {
                    b.extend(&buf[..n]);
                    let excess = b.len().saturating_sub(STDERR_KEPT);
                    b.drain(..excess);
                }
            }
        });
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        std::thread::spawn(move || {
            let mut r = BufReader::new(stdout);
            loop {
                let m = match read_message(&mut r) {
                    Ok(Some(m)) => Ok(m),
                    Ok(None) => break,
                    Err(e) => Err(e.to_string()),
                };
                let stop = m.is_err();
                if tx.send(m).is_err() || stop {
                    break;
                }
            }
        });
        let mut conn = Connection {
            server,
            stdin,
            replies: rx,
            stderr,
            dead: None,
            timeout: cmd.timeout,
        };
        let h = conn
            .call(
                json!({"op": "hello", "protocol": protocol::VERSION}),
                0,
                &[],
            )?
            .header;
        if h.get("ok") != Some(&Value::Bool(true)) {
            return Err(conn.fail(format!(
                "hello refused: {}",
                preview(h.to_string().as_bytes())
            )));
        }
        let version = h.get("protocol").and_then(Value::as_u64);
        if version != Some(protocol::VERSION) {
            return Err(conn.fail(format!(
                "speaks protocol {}; furnace speaks {}",
                version.map_or("(none given)".to_string(), |v| v.to_string()),
                protocol::VERSION
            )));
        }
        let describe = format!(
            "{} {} (model server {:?})",
            h.get("renderer").and_then(Value::as_str).unwrap_or("?"),
            h.get("version").and_then(Value::as_str).unwrap_or("?"),
            cmd.argv.join(" ")
        );
        let precision = match h.get("precision").and_then(Value::as_str) {
            Some("float32") => Precision::F32,
            _ => Precision::F64,
        };
        let models = h
            .get("models")
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        if let Err(why) = validate_models(&models) {
            return Err(conn.fail(format!("hello: {why}")));
        }
        let conn = Arc::new(Mutex::new(conn));
        let mut out = RemoteModels {
            conn: Arc::clone(&conn),
            describe,
            precision,
            bsdfs: Vec::new(),
            phases: Vec::new(),
            emitters: Vec::new(),
        };
        for m in models {
            let name = m
                .get("name")
                .and_then(Value::as_str)
                .unwrap_or("")
                .to_string();
            let flags = m.get("flags").cloned().unwrap_or(json!({}));
            let f = |k: &str| flags.get(k).and_then(Value::as_bool).unwrap_or(false);
            let model = Remote {
                conn: Arc::clone(&conn),
                name: name.clone(),
            };
            match m.get("kind").and_then(Value::as_str) {
                Some("bsdf") => {
                    let flags = BsdfFlags {
                        delta: f("delta"),
                        two_sided: f("two_sided"),
                        transmission: f("transmission"),
                        eta: flags.get("eta").and_then(Value::as_f64).unwrap_or(1.0),
                        lossless: f("lossless"),
                        dispersive: f("dispersive"),
                        min_roughness: flags
                            .get("min_roughness")
                            .and_then(Value::as_f64)
                            .unwrap_or(f64::INFINITY),
                    };
                    out.bsdfs.push(Named {
                        name,
                        model: Arc::new(RemoteBsdf { model, flags }),
                    });
                }
                Some("phase") => {
                    let mean_cosine = flags.get("mean_cosine").and_then(Value::as_f64);
                    out.phases.push(Named {
                        name,
                        model: Arc::new(RemotePhase { model, mean_cosine }),
                    });
                }
                Some("emitter") => {
                    let p = m
                        .get("params")
                        .and_then(|p| p.get("p"))
                        .and_then(Value::as_array)
                        .map(|a| a.iter().filter_map(Value::as_f64).collect::<Vec<_>>())
                        .filter(|a| a.len() == 3)
                        .map_or(Vec3::ZERO, |a| Vec3::new(a[0], a[1], a[2]));
                    out.emitters.push(Named {
                        name,
                        model: Arc::new(RemoteEmitter { model, p }),
                    });
                }
                _ => {}
            }
        }
        Ok(out)
    }
}

/// Checks the hello's model list against docs/model-protocol.md before any flag is trusted:
/// unique non-empty names, a known kind, and flags of the right type and range (a flag selects
/// what the checks test, so an invalid one must not pass as absent).
fn validate_models(models: &[Value]) -> Result<(), String> {
    let mut names = std::collections::HashSet::new();
    for m in models {
        let name = m.get("name").and_then(Value::as_str).unwrap_or("");
        let quoted = format!("{:?}", crate::limits::quote(name));
        if name.is_empty() || name.contains('\n') {
            return Err(format!("a model's name {quoted} is empty or has a newline"));
        }
        if name.len() > crate::limits::MAX_MODEL_NAME {
            return Err(format!(
                "a model's name {quoted} is {} bytes; the limit is {} (check lines and reports name the model)",
                name.len(),
                crate::limits::MAX_MODEL_NAME
            ));
        }
        if !names.insert(name) {
            return Err(format!(
                "the model name {quoted} is served twice; names are unique"
            ));
        }
        let kind = m.get("kind").and_then(Value::as_str);
        let bools: &[&str] = match kind {
            Some("bsdf") => &[
                "delta",
                "two_sided",
                "transmission",
                "lossless",
                "dispersive",
            ],
            Some("emitter") => &["delta"],
            Some("phase") => &[],
            _ => {
                return Err(format!(
                    "model {quoted}: kind {} is not one of bsdf, phase, emitter",
                    crate::limits::quote(&m.get("kind").map_or("none".into(), Value::to_string))
                ))
            }
        };
        let Some(flags) = m.get("flags") else {
            continue;
        };
        let Some(flags) = flags.as_object() else {
            return Err(format!("model {quoted}: flags must be an object"));
        };
        let bad = |k: &str, want: &str| {
            Err(format!(
                "model {quoted}: flag {k} is {}; it must be {want}",
                crate::limits::quote(&flags[k].to_string())
            ))
        };
        for (k, v) in flags {
            let ok = match (kind, k.as_str()) {
                (_, b) if bools.contains(&b) => v.is_boolean(),
                (Some("bsdf"), "eta") => v.as_f64().is_some_and(|e| e.is_finite() && e > 0.0),
                (Some("bsdf"), "min_roughness") => {
                    v.is_null() || v.as_f64().is_some_and(|r| r.is_finite() && r >= 0.0)
                }
                (Some("phase"), "mean_cosine") => {
                    v.is_null() || v.as_f64().is_some_and(|g| (-1.0..=1.0).contains(&g))
                }
                _ => true, // unknown flags are left for later protocol versions
            };
            if !ok {
                let want = match k.as_str() {
                    "eta" => "a finite number > 0",
                    "min_roughness" => "null or a finite number >= 0 (radians)",
                    "mean_cosine" => "null or a number in [-1, 1]",
                    _ => "true or false",
                };
                return bad(k, want);
            }
        }
    }
    Ok(())
}

impl ModelSource for RemoteModels {
    fn describe(&self) -> String {
        self.describe.clone()
    }
    fn precision(&self) -> Precision {
        self.precision
    }
    fn bsdfs(&self) -> Result<Vec<Named<dyn BsdfModel>>, ModelError> {
        self.dead()?;
        Ok(self.bsdfs.clone())
    }
    fn phases(&self) -> Result<Vec<Named<dyn PhaseModel>>, ModelError> {
        self.dead()?;
        Ok(self.phases.clone())
    }
    fn emitters(&self) -> Result<Vec<Named<dyn EmitterModel>>, ModelError> {
        self.dead()?;
        Ok(self.emitters.clone())
    }
}

impl RemoteModels {
    fn dead(&self) -> Result<(), ModelError> {
        match self.conn.lock().ok().and_then(|c| c.dead.clone()) {
            Some(d) => Err(ModelError(d)),
            None => Ok(()),
        }
    }
}

static QUERIES: AtomicU64 = AtomicU64::new(0);
static ROUND_TRIPS: AtomicU64 = AtomicU64::new(0);
static WAIT_NANOS: AtomicU64 = AtomicU64::new(0);

/// What this process has asked of model servers so far: queries (rows), round trips, and
/// seconds spent between sending a batch and holding its checked reply (the server's own work
/// included). The `check` command prints it; `benches/model-protocol.sh` reads it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Traffic {
    /// Rows sent (one query each).
    pub queries: u64,
    /// Batches sent.
    pub round_trips: u64,
    /// Wall time waiting on replies, s.
    pub seconds: f64,
}

/// The model traffic of this process so far.
pub fn traffic() -> Traffic {
    Traffic {
        queries: QUERIES.load(Ordering::Relaxed),
        round_trips: ROUND_TRIPS.load(Ordering::Relaxed),
        seconds: WAIT_NANOS.load(Ordering::Relaxed) as f64 * 1e-9,
    }
}

/// One served model: its connection and name.
struct Remote {
    conn: Arc<Mutex<Connection>>,
    name: String,
}

impl Remote {
    /// Sends `rows` (each `op.request` values) in batches and returns the reply rows (each
    /// `op.reply` values), checked: the row count and width, and no NaN outside rows whose
    /// flags column says "no sample" (`flags_col`).
    fn request(
        &self,
        op: Op,
        rows: &[f64],
        flags_col: Option<usize>,
    ) -> Result<Vec<f64>, ModelError> {
        let n_rows = rows.len() / op.request;
        let mut out = Vec::with_capacity(n_rows * op.reply);
        let mut conn = self
            .conn
            .lock()
            .map_err(|_| ModelError("model server connection poisoned".into()))?;
        for chunk in rows.chunks(protocol::BATCH_ROWS * op.request) {
            let n = chunk.len() / op.request;
            let header = json!({"op": op.name, "model": self.name});
            let start = Instant::now();
            let reply = conn.call(header, op.request, chunk);
            WAIT_NANOS.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
            QUERIES.fetch_add(n as u64, Ordering::Relaxed);
            ROUND_TRIPS.fetch_add(1, Ordering::Relaxed);
            let reply = reply?;
            if reply.header.get("ok") != Some(&Value::Bool(true)) {
                let e = reply
                    .header
                    .get("error")
                    .and_then(Value::as_str)
                    .unwrap_or("no message");
                return Err(ModelError(format!(
                    "model server refused {} on {:?}: {}; {}",
                    op.name,
                    self.name,
                    preview(e.as_bytes()),
                    conn.stderr_tail()
                )));
            }
            if reply.shape() != (n, op.reply) {
                let (rn, rw) = reply.shape();
                return Err(conn.fail(format!(
                    "{} on {:?}: replied {rn} rows of {rw} values for {n} rows of {}",
                    op.name, self.name, op.reply
                )));
            }
            for (i, row) in reply.payload.chunks_exact(op.reply).enumerate() {
                let empty = flags_col.is_some_and(|c| row[c] == 0.0);
                // NaN anywhere, ±∞ but where the protocol allows +∞ (a distance)
                let bad = row.iter().enumerate().find(|&(c, v)| {
                    v.is_nan() || (v.is_infinite() && !(op.infinite == Some(c) && *v > 0.0))
                });
                if let (false, Some((_, v))) = (empty, bad) {
                    // the model's answer, not a broken connection: the server stays up
                    return Err(ModelError(format!(
                        "model server answered {v:?} to {} on {:?} (reply row {}: {row:?}); a value must be a finite number",
                        op.name,
                        self.name,
                        out.len() / op.reply + i
                    )));
                }
            }
            out.extend_from_slice(&reply.payload);
        }
        Ok(out)
    }
}

fn push3(v: &mut Vec<f64>, w: Vec3) {
    v.extend([w.x, w.y, w.z]);
}

fn v3(r: &[f64]) -> Vec3 {
    Vec3::new(r[0], r[1], r[2])
}

fn lanes(r: &[f64]) -> SampledSpectrum {
    SampledSpectrum([r[0], r[1], r[2], r[3]])
}

fn flags(x: f64) -> u32 {
    x as u32
}

struct RemoteBsdf {
    model: Remote,
    flags: BsdfFlags,
}

impl BsdfModel for RemoteBsdf {
    fn flags(&self) -> &BsdfFlags {
        &self.flags
    }
    fn eval(
        &self,
        q: &[(Vec3, Vec3)],
        wl: &Wavelengths,
    ) -> Result<Vec<SampledSpectrum>, ModelError> {
        let mut rows = Vec::with_capacity(q.len() * 10);
        for &(wo, wi) in q {
            push3(&mut rows, wo);
            push3(&mut rows, wi);
            rows.extend(wl.lambda);
        }
        let r = self.model.request(protocol::BSDF_EVAL, &rows, None)?;
        Ok(r.chunks_exact(4).map(lanes).collect())
    }
    fn pdf(&self, q: &[(Vec3, Vec3)], wl: &Wavelengths) -> Result<Vec<f64>, ModelError> {
        let mut rows = Vec::with_capacity(q.len() * 10);
        for &(wo, wi) in q {
            push3(&mut rows, wo);
            push3(&mut rows, wi);
            rows.extend(wl.lambda);
        }
        self.model.request(protocol::BSDF_PDF, &rows, None)
    }
    fn sample(
        &self,
        q: &[(Vec3, [f64; 2], f64)],
        wl: &Wavelengths,
    ) -> Result<Vec<Option<BsdfSample>>, ModelError> {
        let mut rows = Vec::with_capacity(q.len() * 10);
        for &(wo, u, uc) in q {
            push3(&mut rows, wo);
            rows.extend([u[0], u[1], uc]);
            rows.extend(wl.lambda);
        }
        let r = self.model.request(protocol::BSDF_SAMPLE, &rows, Some(8))?;
        Ok(r.chunks_exact(9)
            .map(|r| {
                let f = flags(r[8]);
                (f & protocol::FLAG_SAMPLE != 0).then(|| BsdfSample {
                    wi: v3(r),
                    weight: lanes(&r[3..]),
                    pdf: r[7],
                    delta: f & protocol::FLAG_DELTA != 0,
                })
            })
            .collect())
    }
    fn eta(&self, w: &[Vec3], wl: &Wavelengths) -> Result<Vec<SampledSpectrum>, ModelError> {
        let mut rows = Vec::with_capacity(w.len() * 7);
        for &w in w {
            push3(&mut rows, w);
            rows.extend(wl.lambda);
        }
        match self.model.request(protocol::BSDF_ETA, &rows, None) {
            Ok(r) => Ok(r.chunks_exact(4).map(lanes).collect()),
            // a server without bsdf.eta: η from the flags, which is exact unless dispersive
            Err(e) if e.0.contains("unknown op") && !self.flags.dispersive => Ok(w
                .iter()
                .map(|w| SampledSpectrum::splat(if w.z < 0.0 { self.flags.eta } else { 1.0 }))
                .collect()),
            Err(e) => Err(e),
        }
    }
}

struct RemotePhase {
    model: Remote,
    mean_cosine: Option<f64>,
}

impl RemotePhase {
    fn pairs(q: &[(Vec3, Vec3)]) -> Vec<f64> {
        let mut rows = Vec::with_capacity(q.len() * 10);
        for &(wo, wi) in q {
            push3(&mut rows, wo);
            push3(&mut rows, wi);
            rows.extend([550.0; 4]);
        }
        rows
    }
}

impl PhaseModel for RemotePhase {
    fn mean_cosine(&self) -> Option<f64> {
        self.mean_cosine
    }
    fn eval(&self, q: &[(Vec3, Vec3)]) -> Result<Vec<f64>, ModelError> {
        self.model
            .request(protocol::PHASE_EVAL, &Self::pairs(q), None)
    }
    fn pdf(&self, q: &[(Vec3, Vec3)]) -> Result<Vec<f64>, ModelError> {
        self.model
            .request(protocol::PHASE_PDF, &Self::pairs(q), None)
    }
    fn sample(&self, q: &[(Vec3, [f64; 2])]) -> Result<Vec<PhaseSample>, ModelError> {
        let mut rows = Vec::with_capacity(q.len() * 9);
        for &(wo, u) in q {
            push3(&mut rows, wo);
            rows.extend([u[0], u[1]]);
            rows.extend([550.0; 4]);
        }
        let r = self.model.request(protocol::PHASE_SAMPLE, &rows, None)?;
        Ok(r.chunks_exact(5)
            .map(|r| PhaseSample {
                wi: v3(r),
                weight: r[3],
                pdf: r[4],
            })
            .collect())
    }
}

struct RemoteEmitter {
    model: Remote,
    p: Vec3,
}

impl EmitterModel for RemoteEmitter {
    fn sample(
        &self,
        q: &[([f64; 2], f64)],
        wl: &Wavelengths,
    ) -> Result<Vec<Option<EmitterSample>>, ModelError> {
        let mut rows = Vec::with_capacity(q.len() * 10);
        for &(u, uc) in q {
            push3(&mut rows, self.p);
            rows.extend([u[0], u[1], uc]);
            rows.extend(wl.lambda);
        }
        let r = self
            .model
            .request(protocol::EMITTER_SAMPLE, &rows, Some(9))?;
        Ok(r.chunks_exact(10)
            .map(|r| {
                let f = flags(r[9]);
                (f & protocol::FLAG_SAMPLE != 0).then(|| EmitterSample {
                    wi: v3(r),
                    radiance: lanes(&r[3..]),
                    pdf: r[7],
                    dist: r[8],
                    delta: f & protocol::FLAG_DELTA != 0,
                })
            })
            .collect())
    }
    fn pdf(&self, w: &[Vec3], wl: &Wavelengths) -> Result<Vec<f64>, ModelError> {
        let mut rows = Vec::with_capacity(w.len() * 10);
        for &w in w {
            push3(&mut rows, self.p);
            push3(&mut rows, w);
            rows.extend(wl.lambda);
        }
        self.model.request(protocol::EMITTER_PDF, &rows, None)
    }
}

/// A model server that could not be started: every query fails with why, so the model-level
/// checks of that renderer end as ERROR with the reason (never silently skipped).
pub struct Unavailable(pub String);

impl ModelSource for Unavailable {
    fn describe(&self) -> String {
        format!("unavailable model server: {}", self.0)
    }
    fn bsdfs(&self) -> Result<Vec<Named<dyn BsdfModel>>, ModelError> {
        Err(ModelError(self.0.clone()))
    }
    fn phases(&self) -> Result<Vec<Named<dyn PhaseModel>>, ModelError> {
        Err(ModelError(self.0.clone()))
    }
    fn emitters(&self) -> Result<Vec<Named<dyn EmitterModel>>, ModelError> {
        Err(ModelError(self.0.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::validate_models;
    use serde_json::json;

    #[test]
    fn a_hello_with_invalid_or_duplicate_models_is_refused_by_name() {
        let bsdf = |flags| json!({"name": "m", "kind": "bsdf", "flags": flags});
        assert!(validate_models(&[bsdf(json!({"delta": false, "min_roughness": null}))]).is_ok());
        assert!(validate_models(&[bsdf(json!({"eta": 1.5, "min_roughness": 0.1}))]).is_ok());
        for (flags, says) in [
            (json!({"min_roughness": -5}), "flag min_roughness is -5"),
            (
                json!({"min_roughness": "abc"}),
                "flag min_roughness is \"abc\"",
            ),
            (json!({"eta": -1e308}), "flag eta"),
            (
                json!({"delta": 1}),
                "flag delta is 1; it must be true or false",
            ),
        ] {
            let e = validate_models(&[bsdf(flags)]).unwrap_err();
            assert!(e.contains(says), "{e}");
        }
        let e = validate_models(&[bsdf(json!({})), bsdf(json!({}))]).unwrap_err();
        assert!(e.contains("served twice"), "{e}");
        let e =
            validate_models(&[json!({"name": "p", "kind": "phase", "flags": {"mean_cosine": 2}})])
                .unwrap_err();
        assert!(e.contains("mean_cosine"), "{e}");
        let long = "d".repeat(900_000);
        let e = validate_models(&[json!({"name": long, "kind": "bsdf"})]).unwrap_err();
        assert!(e.len() < 400 && e.contains("900000 bytes"), "{e}");
        let e = validate_models(&[json!({"name": "x", "kind": "light"})]).unwrap_err();
        assert!(e.contains("not one of bsdf, phase, emitter"), "{e}");
    }
}
