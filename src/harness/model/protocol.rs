//! The model protocol's wire format (`docs/model-protocol.md`, version [`VERSION`]): one JSON
//! header line per message, then `n × width` little-endian f64; the ops and their row widths.

use serde_json::{json, Value};
use std::io::{self, BufRead, Read, Write};

/// Protocol version.
pub const VERSION: u64 = 1;

/// Rows per request furnace sends.
pub const BATCH_ROWS: usize = 65_536;

/// Most rows a message may carry (the reader refuses more before allocating).
pub const MAX_ROWS: usize = 1 << 20;

/// Longest header line accepted, bytes.
pub const MAX_HEADER: usize = 1 << 20;

/// An operation: its name, request row width and reply row width.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Op {
    /// Name on the wire.
    pub name: &'static str,
    /// f64 per request row.
    pub request: usize,
    /// f64 per reply row.
    pub reply: usize,
    /// The reply column that may hold +∞ (the distance to a light at infinity); every other
    /// value of a sample must be finite.
    pub infinite: Option<usize>,
}

/// f(wo, wi) per wavelength: wo, wi, λ\[4\] → f\[4\].
pub const BSDF_EVAL: Op = Op {
    name: "bsdf.eval",
    request: 10,
    reply: 4,
    infinite: None,
};
/// pdf(wo, wi): wo, wi, λ\[4\] → pdf.
pub const BSDF_PDF: Op = Op {
    name: "bsdf.pdf",
    request: 10,
    reply: 1,
    infinite: None,
};
/// A sample: wo, u1, u2, uc, λ\[4\] → wi, weight\[4\], pdf, flags.
pub const BSDF_SAMPLE: Op = Op {
    name: "bsdf.sample",
    request: 10,
    reply: 9,
    infinite: None,
};
/// η on the side of w: w, λ\[4\] → η\[4\].
pub const BSDF_ETA: Op = Op {
    name: "bsdf.eta",
    request: 7,
    reply: 4,
    infinite: None,
};
/// p(wo, wi): wo, wi, λ\[4\] → p.
pub const PHASE_EVAL: Op = Op {
    name: "phase.eval",
    request: 10,
    reply: 1,
    infinite: None,
};
/// pdf(wo, wi): wo, wi, λ\[4\] → pdf.
pub const PHASE_PDF: Op = Op {
    name: "phase.pdf",
    request: 10,
    reply: 1,
    infinite: None,
};
/// A sample: wo, u1, u2, λ\[4\] → wi, weight, pdf.
pub const PHASE_SAMPLE: Op = Op {
    name: "phase.sample",
    request: 9,
    reply: 5,
    infinite: None,
};
/// A direction towards the emitter: p, u1, u2, uc, λ\[4\] → wi, radiance\[4\], pdf, dist, flags.
pub const EMITTER_SAMPLE: Op = Op {
    name: "emitter.sample_direction",
    request: 10,
    reply: 10,
    infinite: Some(8),
};
/// The density of a direction: p, wi, λ\[4\] → pdf.
pub const EMITTER_PDF: Op = Op {
    name: "emitter.pdf_direction",
    request: 10,
    reply: 1,
    infinite: None,
};

/// Every op of this version.
pub const OPS: [Op; 9] = [
    BSDF_EVAL,
    BSDF_PDF,
    BSDF_SAMPLE,
    BSDF_ETA,
    PHASE_EVAL,
    PHASE_PDF,
    PHASE_SAMPLE,
    EMITTER_SAMPLE,
    EMITTER_PDF,
];

/// Sample flags (an integer stored as f64): a sample exists.
pub const FLAG_SAMPLE: u32 = 1;
/// The sample is from a Dirac lobe (a point light for emitters).
pub const FLAG_DELTA: u32 = 2;
/// The sample is transmitted.
pub const FLAG_TRANSMISSION: u32 = 4;
/// Only lane 0's weight is meaningful (dispersion).
pub const FLAG_DISPERSIVE: u32 = 8;

/// One message: its header and its payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    /// The header object.
    pub header: Value,
    /// The payload, `n × width` values.
    pub payload: Vec<f64>,
}

impl Message {
    /// `n` and `width` of the header (0, 0 without a payload).
    pub fn shape(&self) -> (usize, usize) {
        let get = |k: &str| self.header.get(k).and_then(Value::as_u64).unwrap_or(0) as usize;
        (get("n"), get("width"))
    }
}

/// Reads one message; Ok(None) at end of input. A header over [`MAX_HEADER`] bytes, a payload
/// over [`MAX_ROWS`] rows of 16 values, or a short payload is an error, before allocating it.
pub fn read_message(r: &mut impl BufRead) -> io::Result<Option<Message>> {
    let mut line = Vec::new();
    let n = r
        .by_ref()
        .take(MAX_HEADER as u64 + 1)
        .read_until(b'\n', &mut line)?;
    if n == 0 {
        return Ok(None);
    }
    if line.last() != Some(&b'\n') {
        return Err(bad(if line.len() > MAX_HEADER {
            format!("header line longer than {MAX_HEADER} bytes")
        } else {
            "the stream ended inside a header line".into()
        }));
    }
    let header: Value = serde_json::from_slice(&line).map_err(|e| {
        bad(format!(
            "header is not a JSON object: {e}: {}",
            preview(&line)
        ))
    })?;
    if !header.is_object() {
        return Err(bad(format!(
            "header is not a JSON object: {}",
            preview(&line)
        )));
    }
    // `n` and `width`, when present, must be counts: a payload announced otherwise (−1, 1.5,
    // "7") cannot be skipped, so the stream would lose its framing
    for k in ["n", "width"] {
        if let Some(v) = header.get(k).filter(|v| v.as_u64().is_none()) {
            return Err(bad(format!(
                "header field {k:?} is {}, not a count of rows or values",
                preview(v.to_string().as_bytes())
            )));
        }
    }
    let get = |k: &str| header.get(k).and_then(Value::as_u64);
    if get("n").is_some() != get("width").is_some() {
        return Err(bad(
            "a header with a payload gives both \"n\" (rows) and \"width\" (values per row)".into(),
        ));
    }
    let payload = match (get("n"), get("width")) {
        (Some(n), Some(w)) => {
            if n as usize > MAX_ROWS || w > 16 {
                return Err(bad(format!(
                    "payload of {n} rows x {w} values is over the limit ({MAX_ROWS} x 16)"
                )));
            }
            let count = (n * w) as usize;
            let mut bytes = vec![0u8; count * 8];
            r.read_exact(&mut bytes)
                .map_err(|e| bad(format!("payload shorter than {n} x {w} values: {e}")))?;
            bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect()
        }
        _ => Vec::new(),
    };
    Ok(Some(Message { header, payload }))
}

/// Writes one message: `header` (with `n` and `width` added when there is a payload) and the
/// payload of rows of `width` values.
pub fn write_message(
    w: &mut impl Write,
    mut header: Value,
    width: usize,
    payload: &[f64],
) -> io::Result<()> {
    if let Some(n) = payload.len().checked_div(width) {
        header["n"] = json!(n);
        header["width"] = json!(width);
    }
    let mut bytes = serde_json::to_vec(&header).map_err(|e| bad(e.to_string()))?;
    bytes.push(b'\n');
    bytes.reserve(payload.len() * 8);
    for v in payload {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    w.write_all(&bytes)?;
    w.flush()
}

fn bad(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

/// At most 120 characters of a line, for messages.
pub fn preview(line: &[u8]) -> String {
    let s = String::from_utf8_lossy(line);
    let s = s.trim_end();
    let cut: String = s.chars().take(120).collect();
    if cut.len() < s.len() {
        format!("{cut}…")
    } else {
        cut
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_round_trip_bit_for_bit() {
        let values = [0.1, -0.0, f64::MIN_POSITIVE, 1e300, 2.5, f64::INFINITY];
        let mut buf = Vec::new();
        write_message(&mut buf, json!({"ok": true}), 3, &values).unwrap();
        write_message(&mut buf, json!({"op": "bye"}), 0, &[]).unwrap();
        let mut r = std::io::Cursor::new(buf);
        let m = read_message(&mut r).unwrap().unwrap();
        assert_eq!(m.shape(), (2, 3));
        assert!(m
            .payload
            .iter()
            .zip(values)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(read_message(&mut r).unwrap().unwrap().header["op"], "bye");
        assert!(read_message(&mut r).unwrap().is_none());
    }

    #[test]
    fn oversized_or_short_messages_are_refused_before_allocation() {
        for text in [
            "{\"n\": 100000000, \"width\": 10}\n".to_string(),
            "{\"n\": 2, \"width\": 1}\n12345678".to_string(),
            "not json\n".to_string(),
            "[1, 2]\n".to_string(),
            format!("{{\"x\": \"{}\"}}", "a".repeat(MAX_HEADER + 10)),
            // counts that are not counts, and a payload announced by half
            "{\"op\": \"eval\", \"n\": -1, \"width\": 3}\n".to_string(),
            "{\"op\": \"eval\", \"n\": 1.5, \"width\": 3}\n".to_string(),
            "{\"op\": \"eval\", \"n\": \"7\", \"width\": 3}\n".to_string(),
            "{\"op\": \"eval\", \"width\": 3}\n".to_string(),
        ] {
            let e = read_message(&mut std::io::Cursor::new(text.into_bytes())).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidData, "{e}");
        }
    }
}
