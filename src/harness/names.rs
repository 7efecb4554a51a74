//! Names of checks and models, matched by simple globs (`*` any run of characters, `?` one),
//! and the nearest of a list of names to a misspelt one.

/// Simple glob: `*` matches any run of characters, `?` one character.
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut pi, mut ni, mut star, mut mark) = (0, 0, None, 0);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

pub use crate::io::suggest::{did_you_mean, nearest};

#[cfg(test)]
mod tests {
    use super::glob_match;

    #[test]
    fn glob() {
        assert!(glob_match("furnace/*", "furnace/sphere[albedo=0.5]"));
        assert!(glob_match("*sphere*", "furnace/sphere"));
        assert!(!glob_match("lambert/*", "furnace/sphere"));
        assert!(glob_match("f?rnace", "furnace"));
        assert!(glob_match("*", ""));
    }
}
