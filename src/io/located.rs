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

/// Reads a whole text file; `what` names it in the error ("the scene file", "the manifest").
pub fn read_text(path: &Path, what: &str) -> Result<String, LocatedError> {
    std::fs::read_to_string(path).map_err(|e| LocatedError {
        file: path.to_path_buf(),
        line: 0,
        column: 0,
        key: String::new(),
        message: format!("cannot read {what}: {e}"),
    })
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
