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
/// `.NAME.tmp-PID-N` is created afresh (never through a link or a pipe someone left under that
/// name) and removed on failure and on Ctrl-C / SIGTERM (only SIGKILL can leave it behind).
/// `write` writes the temporary file. A character device (`/dev/null`) is appended to in
/// place and furnace's standard output or error (`/dev/stdout`, `/dev/fd/2`, …) written
/// through the stream itself, never replaced or reopened; anything else that is no regular
/// file is refused, see [`Destination`].
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> std::io::Result<()>,
) -> std::io::Result<()> {
    use std::io::Write;
    let destination = Destination::of(path)?;
    let name = match path.file_name() {
        Some(name) if !names_no_file(path) => name,
        _ => return Err(std::io::Error::other("the path names no file")),
    };
    let dir = match destination {
        Destination::File => path.parent().unwrap_or(Path::new("")).to_path_buf(),
        _ => std::env::temp_dir(),
    };
    let tmp = fresh_file(&dir, &format!(".{}.tmp", name.to_string_lossy()))?;
    write(tmp.path())?;
    match destination {
        Destination::File => std::fs::rename(tmp.path(), path),
        Destination::Device => {
            let mut from = std::fs::File::open(tmp.path())?;
            let mut to = std::fs::OpenOptions::new().append(true).open(path)?;
            std::io::copy(&mut from, &mut to).map(drop)
        }
        Destination::Stdout | Destination::Stderr => {
            let bytes = std::fs::read(tmp.path())?;
            if destination == Destination::Stdout {
                let mut out = std::io::stdout().lock();
                out.write_all(&bytes)?;
                out.flush()
            } else {
                std::io::stderr().lock().write_all(&bytes)
            }
        }
    }
}

/// Whether `path` ends in no file name of its own: in `/`, `.` or `..` (`Path::file_name`
/// reads `out.exr/.` as `out.exr`, where a rename would fail).
fn names_no_file(path: &Path) -> bool {
    let raw = path.as_os_str().to_string_lossy();
    let last = raw.rsplit('/').next().unwrap_or("");
    path.file_name().is_none() || matches!(last, "" | "." | "..")
}

/// A new, empty file `PREFIX-PID-N` in `dir` (the first N whose name is free), created with
/// `create_new` so that a link or a pipe already under that name is never opened, and
/// registered for removal (on drop, on failure and on interrupt) once it exists.
fn fresh_file(dir: &Path, prefix: &str) -> std::io::Result<super::cleanup::Pending> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    for _ in 0..100 {
        let p = dir.join(format!(
            "{prefix}-{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&p)
        {
            Ok(_) => return Ok(super::cleanup::Pending::new(p)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other(format!(
        "no free temporary name {prefix}-… in {}",
        dir.display()
    )))
}

/// How [`write_atomic`] writes a path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Destination {
    /// A regular file, or nothing yet: a temporary file renamed over it.
    File,
    /// A character device (`/dev/null`): appended to in place.
    Device,
    /// furnace's standard output (`/dev/stdout`, `/dev/fd/1`, `/proc/self/fd/1`): written
    /// through the stream, so a redirection keeps its place and furnace's own lines.
    Stdout,
    /// furnace's standard error (`/dev/stderr`, `/dev/fd/2`, `/proc/self/fd/2`).
    Stderr,
}

impl Destination {
    /// Where `path` leads, or why it cannot be written: a folder; a symbolic link to a file or
    /// to nothing (renaming would replace the link, and following it ourselves would bypass
    /// the kernel's protection of links in shared folders such as /tmp: give the file's own
    /// path); a named pipe, a socket or a block device; another process stream than standard
    /// output or error. Links are followed by the kernel only.
    pub fn of(path: &Path) -> std::io::Result<Destination> {
        use std::io::{Error, ErrorKind};
        match path.to_string_lossy().as_ref() {
            "/dev/stdout" | "/dev/fd/1" | "/proc/self/fd/1" => return Ok(Destination::Stdout),
            "/dev/stderr" | "/dev/fd/2" | "/proc/self/fd/2" => return Ok(Destination::Stderr),
            s if s.starts_with("/dev/fd/") || s.starts_with("/proc/self/fd/") => {
                return Err(Error::new(
                    ErrorKind::InvalidInput,
                    "a stream other than furnace's standard output or error; give /dev/stdout or /dev/stderr",
                ))
            }
            _ => {}
        }
        let link = match std::fs::symlink_metadata(path) {
            // (a file standing where a folder should be: the write, or check_writable, says so)
            Err(e) if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::NotADirectory) => {
                return Ok(Destination::File)
            }
            Err(e) => return Err(e),
            Ok(m) if m.is_file() => return Ok(Destination::File),
            Ok(m) => m.file_type().is_symlink(),
        };
        let m = std::fs::metadata(path).map_err(|e| match e.kind() {
            ErrorKind::NotFound => Error::new(
                ErrorKind::InvalidInput,
                "a symbolic link to nothing: give the file's own path",
            ),
            _ => e,
        })?;
        let t = m.file_type();
        if t.is_dir() {
            Err(Error::new(
                ErrorKind::IsADirectory,
                "a folder is there; give a file name",
            ))
        } else if is_char_device(&t) {
            Ok(Destination::Device)
        } else if link && t.is_file() {
            Err(Error::new(
                ErrorKind::InvalidInput,
                "a symbolic link: furnace replaces an output by renaming a new file over it, which would replace the link; give the file's own path",
            ))
        } else {
            Err(Error::new(
                ErrorKind::InvalidInput,
                "a named pipe, a socket or a block device: outputs go to files or character devices; to stream one, give /dev/stdout",
            ))
        }
    }
}

/// A character device.
#[cfg(unix)]
fn is_char_device(t: &std::fs::FileType) -> bool {
    use std::os::unix::fs::FileTypeExt;
    t.is_char_device()
}

/// A character device (none are told apart here).
#[cfg(not(unix))]
fn is_char_device(_: &std::fs::FileType) -> bool {
    false
}

/// Whether [`write_atomic`] can write `path`, tested before a run spends its time: `Ok` for a
/// character device or furnace's own output stream (see [`Destination`]) and for a file whose
/// nearest existing folder takes a new file (a probe file is created and removed there, as the
/// write's own temporary file will be); otherwise the reason, e.g. a folder at `path`, a file
/// where a folder should be, or no permission. Opens nothing at `path` itself.
pub fn check_writable(path: &Path) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind};
    if Destination::of(path)? != Destination::File {
        return Ok(());
    }
    if names_no_file(path) {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "the path names no file",
        ));
    }
    // the nearest folder that exists (the write creates the missing ones below it)
    let mut dir = path.parent().unwrap_or(Path::new(""));
    let here = loop {
        let here = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        match std::fs::metadata(here) {
            Ok(m) if m.is_dir() => break here,
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
    };
    // created and removed at once (on drop)
    fresh_file(here, ".furnace-write-test")
        .map(drop)
        .map_err(|e| {
            Error::new(
                e.kind(),
                format!("cannot create a file in {}: {e}", here.display()),
            )
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
        let message = super::suggest::plain_message(e.message().trim_end());
        // (toml's own words name u64 where its integers stop at i64::MAX)
        let past_range =
            message == "u64 value was too large" || message == "i64 value was too large";
        // a wrong value names its key: the one its line assigns, when the value is on it
        let key = if message.starts_with("invalid ")
            || message.starts_with("out of range")
            || message.ends_with("value was too large")
        {
            super::suggest::key_of_line(src.text, span.start)
        } else {
            String::new()
        };
        let message = if past_range {
            format!("the integer is past TOML's range (at most {})", i64::MAX)
        } else {
            message
        };
        src.error(span, key, message)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_os = "linux")]
    #[test]
    fn streams_and_devices_are_told_apart_and_links_pipes_and_folders_refused() {
        let d = std::env::temp_dir().join(format!("furnace-located-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        // furnace's own streams by name only, never reopened; other descriptors refused;
        // a character device written in place (classified only: tests never write to it)
        for (path, to) in [
            ("/dev/stdout", Destination::Stdout),
            ("/dev/fd/1", Destination::Stdout),
            ("/proc/self/fd/2", Destination::Stderr),
            ("/dev/null", Destination::Device),
        ] {
            assert_eq!(Destination::of(Path::new(path)).unwrap(), to, "{path}");
            check_writable(Path::new(path)).unwrap();
        }
        for other in ["/dev/fd/0", "/proc/self/fd/7", "/dev/fd/../x"] {
            assert!(Destination::of(Path::new(other)).is_err(), "{other}");
        }
        // a link to a file or to nothing, a folder, a named pipe, a file where a folder
        // should be, a trailing slash: refused, and the link and its file left as they were
        std::fs::write(d.join("t.txt"), "t").unwrap();
        std::os::unix::fs::symlink("t.txt", d.join("l.txt")).unwrap();
        std::os::unix::fs::symlink("gone.txt", d.join("dangling.txt")).unwrap();
        assert!(std::process::Command::new("mkfifo")
            .arg(d.join("pipe"))
            .status()
            .unwrap()
            .success());
        for bad in [
            "l.txt",
            "dangling.txt",
            "pipe",
            "t.txt/x",
            "sub/",
            "t.txt/.",
        ] {
            let p = d.join(bad);
            assert!(check_writable(&p).is_err(), "{bad}");
            assert!(
                write_atomic(&p, |p| std::fs::write(p, "x")).is_err(),
                "{bad}"
            );
        }
        assert!(check_writable(&d).is_err());
        assert!(std::fs::symlink_metadata(d.join("l.txt"))
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read_to_string(d.join("t.txt")).unwrap(), "t");
        // a new file below folders still to be made: the check creates neither folder nor file
        check_writable(&d.join("new/deeper/x.txt")).unwrap();
        assert!(!d.join("new").exists());
        let probes = std::fs::read_dir(&d)
            .unwrap()
            .flatten()
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with(".furnace-write-test")
            })
            .count();
        assert_eq!(probes, 0);
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
