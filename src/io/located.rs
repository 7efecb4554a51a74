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
/// behind). `write` writes the temporary file. A device (`/dev/null`) or one of the process's
/// own streams (`/dev/stdout`, `/dev/fd/N`, `/proc/self/fd/N`) is appended to in place, never
/// replaced; anything else that is no regular file (a folder, a symbolic link, a named pipe,
/// a socket) is refused, see [`Destination`].
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> std::io::Result<()>,
) -> std::io::Result<()> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .ok_or_else(|| std::io::Error::other("the path names no file"))?;
    let tmp_name = format!(
        ".{}.tmp-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    );
    match Destination::of(path)? {
        Destination::File => {
            // removed on failure, on drop after a successful rename (a no-op) and on interrupt
            let tmp = super::cleanup::Pending::new(path.with_file_name(tmp_name));
            write(tmp.path()).and_then(|_| std::fs::rename(tmp.path(), path))
        }
        Destination::InPlace => {
            // written whole first, then appended (no truncation: `--json /dev/stdout >> log`
            // keeps the log)
            let tmp = super::cleanup::Pending::new(std::env::temp_dir().join(tmp_name));
            write(tmp.path())?;
            let mut from = std::fs::File::open(tmp.path())?;
            let mut to = std::fs::OpenOptions::new().append(true).open(path)?;
            std::io::copy(&mut from, &mut to).map(drop)
        }
    }
}

/// How [`write_atomic`] writes a path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Destination {
    /// A regular file, or nothing yet: a temporary file renamed over it.
    File,
    /// A character or block device, or the process's own stream: appended to in place.
    InPlace,
}

impl Destination {
    /// Where `path` leads, or why it cannot be written: a folder; a symbolic link to a file or
    /// to nothing (renaming would replace the link, and following it ourselves would bypass
    /// the kernel's protection of links in shared folders such as /tmp: give the file's own
    /// path); a named pipe or a socket (a pipe someone else left could hang or read the run;
    /// stream through `/dev/stdout`). Links are followed by the kernel only.
    pub fn of(path: &Path) -> std::io::Result<Destination> {
        use std::io::{Error, ErrorKind};
        let own_stream = {
            let s = path.to_string_lossy();
            ["/dev/stdout", "/dev/stderr"].contains(&s.as_ref())
                || s.starts_with("/dev/fd/")
                || s.starts_with("/proc/self/fd/")
        };
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
        } else if own_stream || is_device(&t) {
            Ok(Destination::InPlace)
        } else if link && t.is_file() {
            Err(Error::new(
                ErrorKind::InvalidInput,
                "a symbolic link: furnace replaces an output by renaming a new file over it, which would replace the link; give the file's own path",
            ))
        } else {
            Err(Error::new(
                ErrorKind::InvalidInput,
                "a named pipe or a socket: outputs go to files or devices; to stream one, give /dev/stdout",
            ))
        }
    }
}

/// A character or block device.
#[cfg(unix)]
fn is_device(t: &std::fs::FileType) -> bool {
    use std::os::unix::fs::FileTypeExt;
    t.is_char_device() || t.is_block_device()
}

/// A character or block device (none are told apart here).
#[cfg(not(unix))]
fn is_device(_: &std::fs::FileType) -> bool {
    false
}

/// Whether [`write_atomic`] can write `path`, tested before a run spends its time: `Ok` for a
/// device or the process's own stream (see [`Destination`]) and for a file whose nearest
/// existing folder takes a new file (a probe file is created and removed there, as the write's
/// own temporary file will be); otherwise the reason, e.g. a folder at `path`, a file where a
/// folder should be, or no permission. Opens nothing at `path` itself.
pub fn check_writable(path: &Path) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind};
    use std::sync::atomic::{AtomicU64, Ordering};
    static PROBES: AtomicU64 = AtomicU64::new(0);
    if Destination::of(path)? == Destination::InPlace {
        return Ok(());
    }
    if path.file_name().is_none() || path.as_os_str().to_string_lossy().ends_with('/') {
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
    // a name no other probe uses; registered for removal only once it was created here
    let probe = here.join(format!(
        ".furnace-write-test-{}-{}",
        std::process::id(),
        PROBES.fetch_add(1, Ordering::Relaxed)
    ));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(f) => {
            drop(f);
            drop(super::cleanup::Pending::new(probe));
            Ok(())
        }
        Err(e) => Err(Error::new(
            e.kind(),
            format!("cannot create a file in {}: {e}", here.display()),
        )),
    }
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
    use std::path::PathBuf;

    #[cfg(target_os = "linux")]
    #[test]
    fn streams_are_appended_to_and_links_pipes_and_folders_refused() {
        use std::os::fd::AsRawFd;
        let d = std::env::temp_dir().join(format!("furnace-located-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        // a stream of this process (a file opened for appending, as `>> log` opens stdout):
        // appended to, never truncated or replaced
        let log = d.join("log.txt");
        std::fs::write(&log, "kept\n").unwrap();
        let f = std::fs::OpenOptions::new().append(true).open(&log).unwrap();
        let stream = PathBuf::from(format!("/proc/self/fd/{}", f.as_raw_fd()));
        assert_eq!(Destination::of(&stream).unwrap(), Destination::InPlace);
        check_writable(&stream).unwrap();
        write_atomic(&stream, |p| {
            assert_ne!(
                p,
                stream.as_path(),
                "written whole to a temporary file first"
            );
            std::fs::write(p, "new\n")
        })
        .unwrap();
        drop(f);
        assert_eq!(std::fs::read_to_string(&log).unwrap(), "kept\nnew\n");
        // a device is written in place (classified only: tests never write to /dev/null)
        assert_eq!(
            Destination::of(Path::new("/dev/null")).unwrap(),
            Destination::InPlace
        );
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
        for bad in ["l.txt", "dangling.txt", "pipe", "t.txt/x", "sub/"] {
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
