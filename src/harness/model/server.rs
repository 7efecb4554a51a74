//! A model server: any [`ModelSource`] answering the model protocol on a byte stream. furnace
//! serves its own catalogue this way (`furnace serve-models`), the stand-in through which CI
//! checks that the protocol carries every model-level verdict unchanged.

use super::protocol::{self, preview, read_message, write_message, Message, Op};
use crate::harness::under_test::{BsdfModel, EmitterModel, ModelSource, Named, PhaseModel};
use crate::math::Vec3;
use crate::spectrum::Wavelengths;
use serde_json::{json, Value};
use std::io::{self, BufRead, Write};

/// A deliberate misbehaviour, for testing clients (`furnace serve-models --fault`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// Answer correctly.
    None,
    /// Exit after the hello, as a crash would.
    Crash,
    /// Stop answering after the hello.
    Hang,
    /// Answer NaN in every reply row.
    Nan,
    /// Answer +∞ in every reply row.
    Inf,
    /// Announce one row more than is sent.
    Short,
    /// Claim another protocol version.
    Version,
}

impl Fault {
    /// The fault named `s` (none, crash, hang, nan, inf, short, version).
    pub fn from_name(s: &str) -> Option<Fault> {
        Some(match s {
            "none" => Fault::None,
            "crash" => Fault::Crash,
            "hang" => Fault::Hang,
            "nan" => Fault::Nan,
            "inf" => Fault::Inf,
            "short" => Fault::Short,
            "version" => Fault::Version,
            _ => return None,
        })
    }
}

/// The hello reply describing `source`'s models.
pub fn hello(source: &dyn ModelSource, renderer: &str, fault: Fault) -> Result<Value, String> {
    let mut models = Vec::new();
    for Named { name, model } in source.bsdfs().map_err(|e| e.0)? {
        let f = model.flags();
        models.push(json!({
            "name": name, "kind": "bsdf",
            "flags": {
                "delta": f.delta, "two_sided": f.two_sided, "transmission": f.transmission,
                "eta": f.eta, "lossless": f.lossless, "dispersive": f.dispersive,
                "min_roughness": if f.min_roughness.is_finite() { json!(f.min_roughness) } else { Value::Null },
            },
            "params": {},
        }));
    }
    for Named { name, model } in source.phases().map_err(|e| e.0)? {
        models.push(json!({
            "name": name, "kind": "phase",
            "flags": { "mean_cosine": model.mean_cosine() },
            "params": {},
        }));
    }
    let wl = Wavelengths::fixed([550.0; 4], [1.0; 4]);
    for Named { name, model } in source.emitters().map_err(|e| e.0)? {
        let probe = model.sample(&[([0.5, 0.5], 0.5)], &wl).map_err(|e| e.0)?;
        let delta = probe.first().is_some_and(|s| s.is_some_and(|s| s.delta));
        models.push(json!({
            "name": name, "kind": "emitter",
            "flags": { "delta": delta },
            "params": { "p": [0.0, 0.0, 0.0] },
        }));
    }
    let version = if fault == Fault::Version {
        protocol::VERSION + 1
    } else {
        protocol::VERSION
    };
    Ok(json!({
        "ok": true, "protocol": version, "renderer": renderer,
        "version": env!("CARGO_PKG_VERSION"), "precision": source.precision().name(),
        "models": models,
    }))
}

/// Serves `source` on `input`/`output` until end of input or `bye`.
pub fn serve(
    source: &dyn ModelSource,
    renderer: &str,
    input: &mut impl BufRead,
    output: &mut impl Write,
    fault: Fault,
) -> io::Result<()> {
    let bsdfs = source.bsdfs().map_err(io_err)?;
    let phases = source.phases().map_err(io_err)?;
    let emitters = source.emitters().map_err(io_err)?;
    let mut said_hello = false;
    while let Some(msg) = read_message(input)? {
        let Some(op) = msg.header.get("op").and_then(Value::as_str) else {
            error(output, "the header has no \"op\" string")?;
            continue;
        };
        if op == "bye" {
            return Ok(());
        }
        if op == "hello" {
            let asked = msg.header.get("protocol");
            if asked.and_then(Value::as_u64) != Some(protocol::VERSION) {
                error(
                    output,
                    &format!(
                        "this server speaks protocol {}; the hello asked for {}",
                        protocol::VERSION,
                        asked.map_or("none".to_string(), |v| preview(v.to_string().as_bytes()))
                    ),
                )?;
                continue;
            }
            let h = hello(source, renderer, fault).map_err(io::Error::other)?;
            write_message(output, h, 0, &[])?;
            said_hello = true;
            match fault {
                Fault::Crash => std::process::exit(3),
                Fault::Hang => loop {
                    std::thread::sleep(std::time::Duration::from_secs(3600));
                },
                _ => {}
            }
            continue;
        }
        if !said_hello {
            error(output, "say hello first")?;
            continue;
        }
        match answer(&msg, op, &bsdfs, &phases, &emitters) {
            Ok((width, mut rows)) => {
                if fault == Fault::Nan {
                    rows.iter_mut().for_each(|v| *v = f64::NAN);
                }
                if fault == Fault::Inf {
                    rows.iter_mut().for_each(|v| *v = f64::INFINITY);
                }
                let mut header = json!({"ok": true});
                if fault == Fault::Short {
                    header["n"] = json!(rows.len() / width + 1);
                    header["width"] = json!(width);
                    let mut bytes = serde_json::to_vec(&header).map_err(io::Error::other)?;
                    bytes.push(b'\n');
                    for v in &rows {
                        bytes.extend_from_slice(&v.to_le_bytes());
                    }
                    output.write_all(&bytes)?;
                    output.flush()?;
                    return Ok(());
                }
                write_message(output, header, width, &rows)?;
            }
            Err(e) => error(output, &e)?,
        }
    }
    Ok(())
}

fn io_err(e: crate::harness::under_test::ModelError) -> io::Error {
    io::Error::other(e.0)
}

fn error(output: &mut impl Write, message: &str) -> io::Result<()> {
    write_message(output, json!({"ok": false, "error": message}), 0, &[])
}

/// The rows of a request, checked against the op's width.
fn rows<'a>(msg: &'a Message, op: Op) -> Result<std::slice::ChunksExact<'a, f64>, String> {
    let (n, w) = msg.shape();
    if w != op.request || n * w != msg.payload.len() {
        return Err(format!(
            "{} takes rows of {} values; got {n} rows of {w}",
            op.name, op.request
        ));
    }
    let (directions, numbers, lambda) = layout(op.name);
    for (i, r) in msg.payload.chunks_exact(op.request).enumerate() {
        let refuse = |what: String| Err(format!("{} row {i}: {what}", op.name));
        if let Some(v) = r.iter().find(|v| !v.is_finite()) {
            return refuse(format!("{v:?} is not a finite number"));
        }
        for &(at, name) in directions {
            let w = v3(&r[at..at + 3]);
            if (w.length() - 1.0).abs() > 1e-6 {
                return refuse(format!(
                    "{name} ({:?}, {:?}, {:?}) is not a unit vector",
                    w.x, w.y, w.z
                ));
            }
        }
        for &at in numbers {
            if !(0.0..1.0).contains(&r[at]) {
                return refuse(format!(
                    "the random number {:?} (column {at}) is outside [0, 1)",
                    r[at]
                ));
            }
        }
        if let Some(l) = r[lambda..].iter().find(|l| !(360.0..=830.0).contains(*l)) {
            return refuse(format!("the wavelength {l:?} nm is outside 360-830 nm"));
        }
    }
    Ok(msg.payload.chunks_exact(op.request))
}

/// Where an op's request row holds unit directions (column, name) and random numbers in
/// [0, 1) (columns), and where its four wavelengths start (docs/model-protocol.md's table).
fn layout(op: &str) -> (&'static [(usize, &'static str)], &'static [usize], usize) {
    const WO_WI: &[(usize, &str)] = &[(0, "wo"), (3, "wi")];
    match op {
        "bsdf.sample" => (&[(0, "wo")], &[3, 4, 5], 6),
        "bsdf.eta" => (&[(0, "w")], &[], 3),
        "phase.sample" => (&[(0, "wo")], &[3, 4], 5),
        "emitter.sample_direction" => (&[], &[3, 4, 5], 6),
        "emitter.pdf_direction" => (&[(3, "wi")], &[], 6),
        // bsdf.eval, bsdf.pdf, phase.eval, phase.pdf
        _ => (WO_WI, &[], 6),
    }
}

fn v3(r: &[f64]) -> Vec3 {
    Vec3::new(r[0], r[1], r[2])
}

/// The wavelengths of a row (its last four values), pdf 1.
fn lambdas(r: &[f64]) -> Wavelengths {
    let l = &r[r.len() - 4..];
    Wavelengths::fixed([l[0], l[1], l[2], l[3]], [1.0; 4])
}

/// Calls `f` once per run of consecutive rows with the same wavelengths, in order.
fn by_wavelengths<T>(
    rows: &[&[f64]],
    mut f: impl FnMut(&[&[f64]], &Wavelengths) -> Result<Vec<T>, String>,
) -> Result<Vec<T>, String> {
    let mut out = Vec::with_capacity(rows.len());
    let mut start = 0;
    while start < rows.len() {
        let l = &rows[start][rows[start].len() - 4..];
        let mut end = start + 1;
        while end < rows.len() && &rows[end][rows[end].len() - 4..] == l {
            end += 1;
        }
        out.extend(f(&rows[start..end], &lambdas(rows[start]))?);
        start = end;
    }
    Ok(out)
}

fn find<'a, M: ?Sized>(list: &'a [Named<M>], name: &str, kind: &str) -> Result<&'a M, String> {
    list.iter()
        .find(|m| m.name == name)
        .map(|m| m.model.as_ref())
        .ok_or_else(|| format!("no {kind} named {:?}", crate::limits::quote(name)))
}

/// The reply rows of a request: (width, values).
fn answer(
    msg: &Message,
    op: &str,
    bsdfs: &[Named<dyn BsdfModel>],
    phases: &[Named<dyn PhaseModel>],
    emitters: &[Named<dyn EmitterModel>],
) -> Result<(usize, Vec<f64>), String> {
    use protocol::*;
    let model = msg
        .header
        .get("model")
        .and_then(Value::as_str)
        .unwrap_or("");
    let e = |x: crate::harness::under_test::ModelError| x.0;
    // an op on a model of another kind says what the model is
    let served_as = |why: String| {
        let kind = [
            (bsdfs.iter().any(|m| m.name == model), "a BSDF"),
            (phases.iter().any(|m| m.name == model), "a phase function"),
            (emitters.iter().any(|m| m.name == model), "an emitter"),
        ]
        .into_iter()
        .find_map(|(is, kind)| is.then_some(kind));
        match kind {
            Some(kind) => format!("{why}: it is {kind}"),
            None => why,
        }
    };
    let the_op = OPS
        .iter()
        .find(|o| o.name == op)
        .ok_or_else(|| format!("unknown op {op:?}"))?;
    let rs: Vec<&[f64]> = rows(msg, *the_op)?.collect();
    let mut out = Vec::with_capacity(rs.len() * the_op.reply);
    match op {
        "bsdf.eval" | "bsdf.pdf" => {
            let b = find(bsdfs, model, "BSDF").map_err(served_as)?;
            let eval = op == "bsdf.eval";
            for v in by_wavelengths(&rs, |rs, wl| {
                let q: Vec<_> = rs.iter().map(|r| (v3(r), v3(&r[3..]))).collect();
                Ok(if eval {
                    b.eval(&q, wl)
                        .map_err(e)?
                        .iter()
                        .map(|f| f.0.to_vec())
                        .collect()
                } else {
                    b.pdf(&q, wl).map_err(e)?.iter().map(|p| vec![*p]).collect()
                })
            })? {
                out.extend(v);
            }
        }
        "bsdf.sample" => {
            let b = find(bsdfs, model, "BSDF").map_err(served_as)?;
            let dispersive = b.flags().dispersive;
            let samples = by_wavelengths(&rs, |rs, wl| {
                let q: Vec<_> = rs.iter().map(|r| (v3(r), [r[3], r[4]], r[5])).collect();
                b.sample(&q, wl).map_err(e)
            })?;
            for (s, r) in samples.into_iter().zip(&rs) {
                match s {
                    None => out.extend([0.0; 9]),
                    Some(s) => {
                        // a transmission crosses the surface (wi and wo on opposite sides); a
                        // dispersive model's transmission carries the hero wavelength alone
                        let through = s.wi.z * v3(r).z < 0.0;
                        let flags = FLAG_SAMPLE
                            | if s.delta { FLAG_DELTA } else { 0 }
                            | if through { FLAG_TRANSMISSION } else { 0 }
                            | if through && dispersive {
                                FLAG_DISPERSIVE
                            } else {
                                0
                            };
                        out.extend([s.wi.x, s.wi.y, s.wi.z]);
                        out.extend(s.weight.0);
                        out.extend([s.pdf, flags as f64]);
                    }
                }
            }
        }
        "bsdf.eta" => {
            let b = find(bsdfs, model, "BSDF").map_err(served_as)?;
            for v in by_wavelengths(&rs, |rs, wl| {
                let q: Vec<_> = rs.iter().map(|r| v3(r)).collect();
                b.eta(&q, wl).map_err(e)
            })? {
                out.extend(v.0);
            }
        }
        "phase.eval" | "phase.pdf" => {
            let p = find(phases, model, "phase function").map_err(served_as)?;
            let q: Vec<_> = rs.iter().map(|r| (v3(r), v3(&r[3..]))).collect();
            let v = if op == "phase.eval" {
                p.eval(&q)
            } else {
                p.pdf(&q)
            }
            .map_err(e)?;
            out.extend(v);
        }
        "phase.sample" => {
            let p = find(phases, model, "phase function").map_err(served_as)?;
            let q: Vec<_> = rs.iter().map(|r| (v3(r), [r[3], r[4]])).collect();
            for s in p.sample(&q).map_err(e)? {
                out.extend([s.wi.x, s.wi.y, s.wi.z, s.weight, s.pdf]);
            }
        }
        "emitter.sample_direction" => {
            let m = find(emitters, model, "emitter").map_err(served_as)?;
            for s in by_wavelengths(&rs, |rs, wl| {
                let q: Vec<_> = rs.iter().map(|r| ([r[3], r[4]], r[5])).collect();
                m.sample(&q, wl).map_err(e)
            })? {
                match s {
                    None => out.extend([0.0; 10]),
                    Some(s) => {
                        let flags = FLAG_SAMPLE | if s.delta { FLAG_DELTA } else { 0 };
                        out.extend([s.wi.x, s.wi.y, s.wi.z]);
                        out.extend(s.radiance.0);
                        out.extend([s.pdf, s.dist, flags as f64]);
                    }
                }
            }
        }
        "emitter.pdf_direction" => {
            let m = find(emitters, model, "emitter").map_err(served_as)?;
            for v in by_wavelengths(&rs, |rs, wl| {
                let q: Vec<_> = rs.iter().map(|r| v3(&r[3..])).collect();
                m.pdf(&q, wl).map_err(e)
            })? {
                out.push(v);
            }
        }
        _ => return Err(format!("unknown op {op:?}")),
    }
    Ok((the_op.reply, out))
}
