//! Scene errors: every one names the file, the line and column, the key, and what is allowed.

use std::ops::Range;
use std::path::{Path, PathBuf};

/// An invalid or unreadable scene.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}:{line}:{column}: {}{message}", file.display(), if key.is_empty() { String::new() } else { format!("{key}: ") })]
pub struct SceneError {
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
    ) -> SceneError {
        let (line, column) = self.line_column(span.start);
        SceneError {
            file: self.path.to_path_buf(),
            line,
            column,
            key: key.into(),
            message: message.into(),
        }
    }
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
