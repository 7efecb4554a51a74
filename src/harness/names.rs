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

/// The name among `known` closest to the misspelt `name` by edit distance (insertions,
/// deletions, substitutions; Levenshtein 1966), when it is at most a third of the name's length
/// (at least 1) away: for "did you mean" in errors. None when nothing is that close.
pub fn nearest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let a: Vec<char> = name.chars().collect();
    let limit = (a.len() / 3).max(1);
    known
        .into_iter()
        .map(|k| {
            // one row of the distance table at a time
            let b: Vec<char> = k.chars().collect();
            let mut row: Vec<usize> = (0..=b.len()).collect();
            for (i, ca) in a.iter().enumerate() {
                let mut prev = row[0];
                row[0] = i + 1;
                for (j, cb) in b.iter().enumerate() {
                    let next = (row[j + 1] + 1)
                        .min(row[j] + 1)
                        .min(prev + usize::from(ca != cb));
                    prev = row[j + 1];
                    row[j + 1] = next;
                }
            }
            (row[b.len()], k)
        })
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, k)| k)
}

/// `; did you mean NAME?` for [`nearest`], or nothing.
pub fn did_you_mean<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    nearest(name, known).map_or(String::new(), |k| format!("; did you mean {k:?}?"))
}

#[cfg(test)]
mod tests {
    use super::{glob_match, nearest};

    #[test]
    fn the_nearest_name_is_found_within_a_third_of_its_length() {
        let kinds = ["furnace", "lambert", "half_space"];
        assert_eq!(nearest("furnance", kinds), Some("furnace"));
        assert_eq!(nearest("lamber", kinds), Some("lambert"));
        assert_eq!(nearest("sppp", ["spp", "width"]), Some("spp"));
        assert_eq!(nearest("zzz", kinds), None);
        assert_eq!(nearest("", ["a"]), Some("a"));
    }

    #[test]
    fn glob() {
        assert!(glob_match("furnace/*", "furnace/sphere[albedo=0.5]"));
        assert!(glob_match("*sphere*", "furnace/sphere"));
        assert!(!glob_match("lambert/*", "furnace/sphere"));
        assert!(glob_match("f?rnace", "furnace"));
        assert!(glob_match("*", ""));
    }
}
