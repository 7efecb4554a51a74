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
/// behind). `write` writes the temporary file. A symbolic link at `path` stays: the file it
/// points to is replaced. A device, FIFO or socket at `path` is written in place (`-o
/// /dev/null` must not replace the device), so that write is not atomic; a folder is refused.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> std::io::Result<()>,
) -> std::io::Result<()> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let path = &link_target(path)?;
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(std::io::Error::new(
                std::io::ErrorKind::IsADirectory,
                "a folder is there; give a file name",
            ))
        }
        Ok(m) if !m.is_file() => return write(path),
        _ => {}
    }
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

/// `path` with its symbolic links followed to the file they name (which need not exist yet);
/// `path` itself when it is no link. A chain of more than 40 links is an error (a loop).
fn link_target(path: &Path) -> std::io::Result<std::path::PathBuf> {
    // a link to a device or a pipe (/dev/stdout: /proc/self/fd/1, then "pipe:[N]", which names
    // no file) is written through the link
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return Ok(path.to_path_buf());
    }
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let to = std::fs::read_link(&p)?;
                p = match p.parent() {
                    Some(dir) if to.is_relative() => dir.join(to),
                    _ => to,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(std::io::Error::other(
        "more than 40 symbolic links in a row (a loop?)",
    ))
}

/// Whether [`write_atomic`] can write `path`, tested before a run spends its time: `Ok` for a
/// device, FIFO or socket already there (written in place) and for a file whose nearest
/// existing folder takes a new file (one is created and removed there, as the write's own
/// temporary file will be); otherwise the reason, e.g. a folder at `path`, a file where a
/// folder should be, or no permission.
pub fn check_writable(path: &Path) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind};
    let path = &link_target(path)?;
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(Error::new(
                ErrorKind::IsADirectory,
                "a folder is there; give a file name",
            ))
        }
        Ok(m) if !m.is_file() => return Ok(()),
        _ => {}
    }
    // the nearest folder that exists (the write creates the missing ones below it)
    let mut dir = path.parent().unwrap_or(Path::new(""));
    loop {
        let here = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        match std::fs::metadata(here) {
            Ok(m) if m.is_dir() => break,
            Ok(_) => {
                return Err(Error::new(
                    ErrorKind::NotADirectory,
                    format!("{} is a file, not a folder", here.display()),
                ))
            }
            Err(e) if e.kind() == ErrorKind::NotFound => {
                dir = dir.parent().unwrap_or(Path::new(""));
            }
            Err(e) => return Err(e),
        }
    }
    let here = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let probe = super::cleanup::Pending::new(
        here.join(format!(".furnace-write-test-{}", std::process::id())),
    );
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(probe.path())
        .map(drop)
        .or_else(|e| match e.kind() {
            // a probe left by an earlier run of this process id: the folder takes files
            ErrorKind::AlreadyExists => Ok(()),
            _ => Err(Error::new(
                e.kind(),
                format!("cannot create a file in {}: {e}", here.display()),
            )),
        })
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

    #[cfg(unix)]
    #[test]
    fn writes_go_through_links_and_into_devices_and_a_link_loop_is_an_error() {
        let d = std::env::temp_dir().join(format!("furnace-located-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        // a link stays a link; the file it names (created here) is written
        std::os::unix::fs::symlink("t.txt", d.join("l.txt")).unwrap();
        write_atomic(&d.join("l.txt"), |p| std::fs::write(p, "x")).unwrap();
        assert!(std::fs::symlink_metadata(d.join("l.txt"))
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read_to_string(d.join("t.txt")).unwrap(), "x");
        // a device is written in place
        write_atomic(Path::new("/dev/null"), |p| {
            assert_eq!(p, Path::new("/dev/null"));
            std::fs::write(p, "x")
        })
        .unwrap();
        check_writable(Path::new("/dev/null")).unwrap();
        // a loop of links, a folder, and a file standing where a folder should be
        std::os::unix::fs::symlink("b", d.join("a")).unwrap();
        std::os::unix::fs::symlink("a", d.join("b")).unwrap();
        assert!(write_atomic(&d.join("a"), |p| std::fs::write(p, "x")).is_err());
        assert!(check_writable(&d).is_err());
        assert!(check_writable(&d.join("t.txt/x")).is_err());
        check_writable(&d.join("new/deeper/x.txt")).unwrap();
        assert!(!d.join("new").exists(), "the check creates no folder");
        let _ = std::fs::remove_dir_all(&d);
    }

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
