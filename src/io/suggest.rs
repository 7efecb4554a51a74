//! Plainer words for a TOML input's type and key errors: the nearest known name to a misspelt
//! one ("did you mean"), and serde's Rust type names (`i64`, `f64`) said as a user's words.

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

/// serde's message for a TOML value, in a user's words: in a wrong-type message ("invalid
/// type: …"), Rust's integer and float type names become "an integer" and "a number" (an
/// out-of-range value's message keeps its type name, which states the range); an unknown
/// field gets "did you mean" for the nearest of the fields the message lists.
pub fn plain_message(message: &str) -> String {
    let mut out = message.to_string();
    let wrong_type = message.starts_with("invalid type:");
    for (rust, plain) in [
        ("expected i64", "expected an integer"),
        ("expected u64", "expected a whole number ≥ 0"),
        ("expected u32", "expected a whole number ≥ 0"),
        ("expected usize", "expected a whole number ≥ 0"),
        ("expected f64", "expected a number"),
        ("expected f32", "expected a number"),
    ] {
        if let Some(rest) = out.strip_suffix(rust).filter(|_| wrong_type) {
            out = format!("{rest}{plain}");
        }
    }
    // serde: "unknown field `X`, expected one of `a`, `b`". A table of one field gets
    // "expected `a`", which already names the only choice, so no suggestion is added.
    if let Some(rest) = out.strip_prefix("unknown field `") {
        if let Some((name, listed)) = rest.split_once("`, expected one of ") {
            let known: Vec<&str> = listed
                .split('`')
                .skip(1)
                .step_by(2)
                .filter(|k| !k.is_empty())
                .collect();
            if let Some(k) = nearest(name, known) {
                out.push_str(&format!("; did you mean `{k}`?"));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{nearest, plain_message};

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
    fn serde_messages_name_types_plainly_and_suggest_the_nearest_field() {
        assert_eq!(
            plain_message("invalid type: string \"1024\", expected i64"),
            "invalid type: string \"1024\", expected an integer"
        );
        assert_eq!(
            plain_message("invalid type: string \"x\", expected f64"),
            "invalid type: string \"x\", expected a number"
        );
        assert_eq!(
            plain_message("unknown field `sppp`, expected one of `width`, `height`, `spp`"),
            "unknown field `sppp`, expected one of `width`, `height`, `spp`; did you mean `spp`?"
        );
        assert_eq!(
            plain_message("unknown field `spq`, expected `spp`"),
            "unknown field `spq`, expected `spp`"
        );
        // other messages unchanged, among them an out-of-range value's (its type states the
        // range)
        assert_eq!(
            plain_message("invalid value: integer `5000000000`, expected u32"),
            "invalid value: integer `5000000000`, expected u32"
        );
        assert_eq!(
            plain_message("missing field `camera`"),
            "missing field `camera`"
        );
    }
}
