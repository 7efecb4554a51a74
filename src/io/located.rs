//! Located errors in text files (scenes, manifests, renderer tables, regions, measurements):
//! every one names the file, the line and column, the key, and what is allowed; and the one
//! TOML loader every caller uses.

use serde::de::DeserializeOwned;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// An invalid or unreadable input file, located by line and column (0:0 when the file could
/// not be read at all, and then not shown).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}{}: {}{message}", file.display(), if *line > 0 { format!(":{line}:{column}") } else { String::new() }, if key.is_empty() { String::new() } else { format!("{key}: ") })]
pub struct LocatedError {
    /// The file at fault (the scene, or a CSV it references).
    pub file: PathBuf,
    /// 1-based line (0 when the file could not be read at all).
    pub line: usize,
    /// 1-based column in characters.
    pub column: usize,
    /// Dotted path of the offending key, e.g. `materials.white.reflectance`.
    pub key: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

/// A source text with its path, for turning byte spans into line/column errors.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    /// Path shown in errors.
    pub path: &'a Path,
    /// The file's text.
    pub text: &'a str,
}

impl Source<'_> {
    /// 1-based (line, column) of byte offset `at`.
    pub fn line_column(&self, at: usize) -> (usize, usize) {
        let mut at = at.min(self.text.len());
        while !self.text.is_char_boundary(at) {
            at -= 1;
        }
        let before = &self.text[..at];
        let line = before.matches('\n').count() + 1;
        let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, column)
    }

    /// An error at `span` about `key`.
    pub fn error(
        &self,
        span: Range<usize>,
        key: impl Into<String>,
        message: impl Into<String>,
    ) -> LocatedError {
        let (line, column) = self.line_column(span.start);
        LocatedError {
            file: self.path.to_path_buf(),
            line,
            column,
            key: key.into(),
            message: message.into(),
        }
    }
}

/// The error of a scene, manifest or other located input.
pub type SceneError = LocatedError;

/// Reads a whole text file of at most [`crate::limits::MAX_TEXT_BYTES`]; `what` names it in
/// the error ("the scene file", "the manifest"). Invalid UTF-8 is an error.
pub fn read_text(path: &Path, what: &str) -> Result<String, LocatedError> {
    let at = |message: String| LocatedError {
        file: path.to_path_buf(),
        line: 0,
        column: 0,
        key: String::new(),
        message,
    };
    let bytes = read_capped(path, crate::limits::MAX_TEXT_BYTES)
        .map_err(|e| at(format!("cannot read {what}: {e}")))?;
    String::from_utf8(bytes).map_err(|e| at(format!("cannot read {what}: not UTF-8 text ({e})")))
}

/// Writes a file through a temporary file in the same folder renamed over `path`, so that a
/// failed or interrupted write leaves what was at `path` as it was; the temporary
/// `.NAME.tmp-PID-N` is removed on failure and on Ctrl-C / SIGTERM (only SIGKILL can leave it
/// behind). `write` writes the temporary file.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> std::io::Result<()>,
) -> std::io::Result<()> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .ok_or_else(|| std::io::Error::other("the path names no file"))?;
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    // removed on failure, on drop after a successful rename (a no-op) and on interrupt
    let tmp = super::cleanup::Pending::new(tmp);
    write(tmp.path()).and_then(|_| std::fs::rename(tmp.path(), path))
}

/// A text file of at most [`crate::limits::MAX_TEXT_BYTES`] (see [`read_capped`]).
pub fn read_small_text(path: &Path) -> std::io::Result<String> {
    String::from_utf8(read_capped(path, crate::limits::MAX_TEXT_BYTES)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text ({e})"),
        )
    })
}

/// Reads a regular file of at most `cap` bytes: a FIFO, a device or a directory is refused
/// before it is opened (reading one could block or never end), and a larger file before it is
/// read whole.
pub fn read_capped(path: &Path, cap: u64) -> std::io::Result<Vec<u8>> {
    use std::io::{Error, ErrorKind, Read};
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "not a regular file (a FIFO, a device or a directory)",
        ));
    }
    if meta.len() > cap {
        return Err(Error::new(
            ErrorKind::InvalidData,
            format!("{} bytes; the limit is {cap}", meta.len()),
        ));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(path)?
        .take(cap + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(Error::new(
            ErrorKind::InvalidData,
            format!("more than {cap} bytes (the file grew while it was read)"),
        ));
    }
    Ok(bytes)
}

/// Parses TOML text into `T`; a syntax or type error (unknown key, wrong type) is located.
pub fn parse_toml<T: DeserializeOwned>(src: &Source) -> Result<T, LocatedError> {
    toml::from_str(src.text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        src.error(span, "", e.message().trim_end().to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_and_column_count_characters() {
        let s = Source {
            path: Path::new("a.toml"),
            text: "x = 1\nλ = 2\n  y = 3",
        };
        assert_eq!(s.line_column(0), (1, 1));
        assert_eq!(s.line_column(6), (2, 1));
        // 'y' after two spaces on line 3; the λ is 2 bytes but one character
        let at = s.text.find('y').unwrap();
        assert_eq!(s.line_column(at), (3, 3));
    }
}
