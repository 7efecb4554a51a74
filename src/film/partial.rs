//! Partial films: one part of a sharded render with its exact accumulator state, and the
//! exact merge of the parts into the film of the single run (see [`super::blocks`]). File
//! format (`.film`, docs/formats.md "Partial films"): the line `furnace-partial-film 1`, one
//! line of JSON ([`Header`]), then for each piece, pixel (row-major) and channel (X, Y, Z, R,
//! G, B) the mean and the central sums m2, m3, m4 as little-endian f64.

use super::blocks::{check_tiling, BlockFold, Piece, Span, TilingError};
use super::{merge_pixels, Film, Pixel};
use serde::{Deserialize, Serialize};
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// First line of a partial film file.
pub const MAGIC: &str = "furnace-partial-film 1";
/// Longest header line read, bytes.
const MAX_HEADER: u64 = 1 << 20;
/// Most pieces one part may hold (a part of at most 2^62 blocks has fewer than 126).
const MAX_PIECES: usize = 128;
/// Bytes per pixel and piece: 6 channels × (mean, m2, m3, m4).
const PIXEL_BYTES: u64 = 6 * 4 * 8;

/// What a part says about itself and the run it belongs to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// furnace version that rendered the part.
    pub furnace_version: String,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Blocks of the whole run (camera renders: spp in blocks of `render::BLOCK_SAMPLES`;
    /// light tracing: its fixed chunks).
    pub total_blocks: u64,
    /// The pieces stored, in order: [first block, log2 of the block count, samples].
    pub pieces: Vec<(u64, u32, u64)>,
    /// Paths cut by the path-length guard in this part.
    pub truncated_paths: u64,
    /// Hash of everything the render depends on besides these settings (the loaded scene).
    pub scene_fingerprint: String,
    /// The run's settings as the EXR attributes of the merged image (name, value); parts of
    /// one run have the same list.
    pub attributes: Vec<(String, String)>,
}

impl Header {
    /// The blocks this part covers, as tree nodes.
    pub fn spans(&self) -> Vec<Span> {
        self.pieces
            .iter()
            .map(|&(start, level, _)| Span { start, level })
            .collect()
    }

    /// What must agree between parts of one run, as (field, value) for error messages.
    fn identity(&self) -> Vec<(String, String)> {
        let mut id = vec![
            ("furnace version".into(), self.furnace_version.clone()),
            ("size".into(), format!("{}x{}", self.width, self.height)),
            ("total blocks".into(), self.total_blocks.to_string()),
            ("scene fingerprint".into(), self.scene_fingerprint.clone()),
        ];
        id.extend(self.attributes.iter().cloned());
        id
    }
}

/// Why a partial film cannot be written, read or merged.
#[derive(Debug, thiserror::Error)]
pub enum PartialFilmError {
    /// The file system refused.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// The file is not a partial film furnace can read.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Two parts are of different runs.
    #[error("{a} and {b} are parts of different runs: {field} {va:?} vs {vb:?}")]
    Mismatch {
        /// First file.
        a: PathBuf,
        /// Second file.
        b: PathBuf,
        /// The setting that differs.
        field: String,
        /// Its value in `a`.
        va: String,
        /// Its value in `b`.
        vb: String,
    },
    /// The parts do not cover the run exactly once.
    #[error("the parts do not make the whole run: {0}{1}")]
    Tiling(TilingError, String),
    /// No part was given.
    #[error("no partial films to merge")]
    Empty,
}

/// One part of a render: its header and pieces (each piece a whole image of pixels).
#[derive(Debug, Clone, PartialEq)]
pub struct PartialFilm {
    /// Settings and layout.
    pub header: Header,
    /// The pieces' pixel states, in the order of `header.pieces`.
    pub pieces: Vec<Vec<Pixel>>,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> PartialFilmError + '_ {
    move |source| PartialFilmError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn format_err(path: &Path, message: impl Into<String>) -> PartialFilmError {
    PartialFilmError::Format {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

impl PartialFilm {
    /// A part of a render of `width`×`height` pixels and `total_blocks` blocks from its pieces
    /// (in block order), `count` giving the count each pixel holds in a piece (samples, light
    /// paths or runs); the attributes are left empty for the caller.
    pub fn new(
        (width, height): (usize, usize),
        total_blocks: u64,
        pieces: Vec<Piece<Vec<Pixel>>>,
        count: impl Fn(&Span) -> u64,
        truncated_paths: u64,
        scene_fingerprint: String,
    ) -> PartialFilm {
        PartialFilm {
            header: Header {
                furnace_version: env!("CARGO_PKG_VERSION").to_string(),
                width,
                height,
                total_blocks,
                pieces: pieces
                    .iter()
                    .map(|p| (p.span.start, p.span.level, count(&p.span)))
                    .collect(),
                truncated_paths,
                scene_fingerprint,
                attributes: Vec::new(),
            },
            pieces: pieces.into_iter().map(|p| p.state).collect(),
        }
    }

    /// Writes the part to `path` (through a temporary file: a failed write leaves what was
    /// there). Every pixel of a piece must hold the piece's sample count.
    pub fn write(&self, path: &Path) -> Result<(), PartialFilmError> {
        let h = &self.header;
        if h.pieces.len() != self.pieces.len() {
            return Err(format_err(path, "header and pieces disagree"));
        }
        for (&(_, _, n), piece) in h.pieces.iter().zip(&self.pieces) {
            let wrong = piece.iter().any(|p| p.count() != n);
            if piece.len() != h.width * h.height || wrong {
                return Err(format_err(
                    path,
                    format!("a piece's pixels do not all hold {n} samples"),
                ));
            }
        }
        let header = serde_json::to_string(h).map_err(|e| format_err(path, e.to_string()))?;
        crate::io::write_atomic(path, |tmp| {
            let mut out = BufWriter::new(std::fs::File::create(tmp)?);
            writeln!(out, "{MAGIC}")?;
            writeln!(out, "{header}")?;
            for piece in &self.pieces {
                for p in piece {
                    for m in p.channels() {
                        for v in m.moments() {
                            out.write_all(&v.to_le_bytes())?;
                        }
                    }
                }
            }
            out.into_inner().map_err(|e| e.into_error())?.sync_all()
        })
        .map_err(io_err(path))
    }
}

/// An open partial film whose header has been read and checked against the file's length.
pub struct PartFile {
    /// The file.
    pub path: PathBuf,
    /// Its header.
    pub header: Header,
    reader: BufReader<std::fs::File>,
    next_piece: usize,
}

impl PartFile {
    /// Opens `path` and reads its header. Refuses, before reading any pixel: a file that is
    /// not regular, a wrong first line, a header over 1 MiB or with unknown fields, an image
    /// over `limits::image`, pieces that are not nodes of the run's block tree, and a length
    /// that is not exactly the header's plus the pixels it announces.
    pub fn open(path: &Path) -> Result<PartFile, PartialFilmError> {
        let meta = std::fs::metadata(path).map_err(io_err(path))?;
        if !meta.is_file() {
            return Err(format_err(
                path,
                "not a regular file (a FIFO, a device or a directory)",
            ));
        }
        let file = std::fs::File::open(path).map_err(io_err(path))?;
        let mut reader = BufReader::new(file);
        let mut head = Vec::new();
        let mut limited = (&mut reader).take(MAX_HEADER);
        let magic_len = limited.read_until(b'\n', &mut head).map_err(io_err(path))?;
        if head != format!("{MAGIC}\n").as_bytes() {
            return Err(format_err(
                path,
                format!("not a furnace partial film (its first line is not {MAGIC:?})"),
            ));
        }
        head.clear();
        let header_len = limited.read_until(b'\n', &mut head).map_err(io_err(path))?;
        if head.last() != Some(&b'\n') {
            return Err(format_err(
                path,
                "the header line is cut short or longer than 1 MiB",
            ));
        }
        let header: Header = serde_json::from_slice(&head)
            .map_err(|e| format_err(path, format!("bad header: {e}")))?;
        let h = &header;
        crate::limits::image(h.width as u64, h.height as u64)
            .map_err(|e| format_err(path, e.to_string()))?;
        if h.pieces.is_empty() || h.pieces.len() > MAX_PIECES {
            return Err(format_err(
                path,
                format!("{} pieces; a part holds 1 to {MAX_PIECES}", h.pieces.len()),
            ));
        }
        for &(start, level, n) in &h.pieces {
            let fits = level < 63
                && start % (1u64 << level) == 0
                && start
                    .checked_add(1u64 << level)
                    .is_some_and(|e| e <= h.total_blocks);
            if !fits || n == 0 {
                return Err(format_err(
                    path,
                    format!(
                        "piece (first block {start}, level {level}, {n} samples) is not a node of a run of {} blocks",
                        h.total_blocks
                    ),
                ));
            }
        }
        let pixels = (h.width * h.height) as u128;
        let expected = (magic_len + header_len) as u128
            + h.pieces.len() as u128 * pixels * PIXEL_BYTES as u128;
        if meta.len() as u128 != expected {
            return Err(format_err(
                path,
                format!(
                    "{} bytes, but its header announces {expected} (the file is cut short or was altered)",
                    meta.len()
                ),
            ));
        }
        Ok(PartFile {
            path: path.to_path_buf(),
            header,
            reader,
            next_piece: 0,
        })
    }

    /// Reads the next piece, or None after the last.
    pub fn next_piece(&mut self) -> Result<Option<Piece<Vec<Pixel>>>, PartialFilmError> {
        let Some(&(start, level, n)) = self.header.pieces.get(self.next_piece) else {
            return Ok(None);
        };
        self.next_piece += 1;
        let count = self.header.width * self.header.height;
        let mut pixels = Vec::with_capacity(count);
        let mut buf = vec![0u8; PIXEL_BYTES as usize];
        for _ in 0..count {
            self.reader
                .read_exact(&mut buf)
                .map_err(io_err(&self.path))?;
            let mut v = buf
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")));
            let moments: [[f64; 4]; 6] =
                std::array::from_fn(|_| std::array::from_fn(|_| v.next().expect("24 values")));
            // a sum of squared deviations is never negative, whatever the rounding (each
            // update and each merge adds a product of two factors of one sign)
            if moments.iter().any(|m| m[1] < 0.0) {
                return Err(format_err(
                    &self.path,
                    format!(
                        "pixel {} of piece {}: a negative sum of squared deviations (the file was altered)",
                        pixels.len(),
                        self.next_piece
                    ),
                ));
            }
            pixels.push(Pixel::from_moments(n, moments));
        }
        Ok(Some(Piece {
            span: Span { start, level },
            state: pixels,
        }))
    }
}

/// Merges the parts in `paths` (any order) into the single run's film, reading one piece at a
/// time (memory: a few images, not all parts). Refuses parts of different runs (naming the
/// setting) and blocks missing or covered twice (naming the files).
pub fn merge_files(paths: &[PathBuf]) -> Result<(Header, Film), PartialFilmError> {
    let mut parts = paths
        .iter()
        .map(|p| PartFile::open(p))
        .collect::<Result<Vec<_>, _>>()?;
    let first = parts.first().ok_or(PartialFilmError::Empty)?;
    let id = first.header.identity();
    for part in &parts[1..] {
        let other = part.header.identity();
        let differs = id
            .iter()
            .zip(&other)
            .find(|(a, b)| a != b)
            .map(|(a, b)| (a.0.clone(), a.1.clone(), b.1.clone()))
            .or_else(|| {
                (id.len() != other.len()).then(|| {
                    (
                        "attribute list".into(),
                        format!("{} entries", id.len()),
                        format!("{} entries", other.len()),
                    )
                })
            });
        if let Some((field, va, vb)) = differs {
            return Err(PartialFilmError::Mismatch {
                a: first.path.clone(),
                b: part.path.clone(),
                field,
                va,
                vb,
            });
        }
    }
    let spans: Vec<Span> = parts.iter().flat_map(|p| p.header.spans()).collect();
    let total = first.header.total_blocks;
    check_tiling(&spans, total).map_err(|e| {
        let files = |r: &std::ops::Range<u64>| {
            parts
                .iter()
                .filter(|p| {
                    p.header
                        .spans()
                        .iter()
                        .any(|s| s.start < r.end && r.start < s.end())
                })
                .map(|p| p.path.display().to_string())
                .collect::<Vec<_>>()
        };
        let detail = match &e {
            TilingError::Overlap(r) => format!(" (in {})", files(r).join(" and ")),
            TilingError::Missing(_) => format!(
                " (of the run's {total} blocks; {} given: is a part missing?)",
                match parts.len() {
                    1 => "1 part".to_string(),
                    n => format!("{n} parts"),
                }
            ),
        };
        PartialFilmError::Tiling(e, detail)
    })?;
    // the pieces' sample counts: no sum that wraps, and for camera paths the run's spp
    let mut total: u64 = 0;
    for part in &parts {
        for &(_, _, n) in &part.header.pieces {
            total = total.checked_add(n).ok_or_else(|| {
                format_err(
                    &part.path,
                    "its pieces' sample counts overflow a 64-bit sum",
                )
            })?;
        }
    }
    let attribute = |name: &str| {
        first
            .header
            .attributes
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    };
    if attribute("furnace.integrator") == Some("path") {
        if let Some(spp) = attribute("furnace.spp").and_then(|s| s.parse::<u64>().ok()) {
            if total != spp {
                return Err(format_err(
                    &first.path,
                    format!("the parts' pieces hold {total} samples per pixel, but the run's furnace.spp is {spp} (a file was altered)"),
                ));
            }
        }
    }
    let header = first.header.clone();
    parts.sort_by_key(|p| p.header.pieces[0].0);
    let mut fold = BlockFold::new(0);
    let mut truncated = 0u64;
    for part in &mut parts {
        truncated = truncated.saturating_add(part.header.truncated_paths);
        while let Some(piece) = part.next_piece()? {
            fold.push_piece(piece, &|a: &mut Vec<Pixel>, b: &Vec<Pixel>| {
                merge_pixels(a, b)
            });
        }
    }
    let pixels = fold
        .finish(&|a: &mut Vec<Pixel>, b: &Vec<Pixel>| merge_pixels(a, b))
        .ok_or(PartialFilmError::Empty)?;
    let film = Film {
        width: header.width,
        height: header.height,
        pixels,
        truncated_paths: truncated,
    };
    Ok((header, film))
}
