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

/// serde quotes a float it refuses in full decimals (`1e300` as 301 digits): quote it as Rust's
/// `{:?}` writes it, in exponent form past 1e16 and below 1e-4.
fn short_floats(message: &str) -> String {
    const AT: &str = "floating point `";
    let Some(start) = message.find(AT).map(|i| i + AT.len()) else {
        return message.to_string();
    };
    let Some(len) = message[start..].find('`') else {
        return message.to_string();
    };
    match message[start..start + len].parse::<f64>() {
        Ok(v) => format!("{}{v:?}{}", &message[..start], &message[start + len..]),
        Err(_) => message.to_string(),
    }
}

/// serde's message for a TOML value, in a user's words: in a wrong-type message ("invalid
/// type: …"), Rust's integer and float type names become "an integer" and "a number" (an
/// out-of-range value's message keeps its type name, which states the range); an unknown
/// field gets "did you mean" for the nearest of the fields the message lists.
pub fn plain_message(message: &str) -> String {
    let mut out = short_floats(message);
    let message = out.as_str();
    let wrong_type = message.starts_with("invalid type:");
    // a whole number beyond its type ("integer `…` as i128, expected i64", "invalid value:
    // integer `…`, expected u32") is out of range, not of the wrong type: say the range
    let integer = message.starts_with("invalid type: integer") && message.contains(" as i128")
        || message.starts_with("invalid value: integer");
    if integer {
        for (rust, range) in [
            ("i64", "-9223372036854775808 to 9223372036854775807"),
            ("u64", "0 to 18446744073709551615"),
            ("u32", "0 to 4294967295"),
        ] {
            if let Some(rest) = message.strip_suffix(&format!("expected {rust}")) {
                let rest = rest
                    .replacen("invalid type:", "out of range:", 1)
                    .replacen("invalid value:", "out of range:", 1)
                    .replacen(" as i128", "", 1);
                return format!("{rest}expected an integer from {range}");
            }
        }
    }
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

/// The key a value at byte `at` of `text` is assigned to: the last `key =` before it on its
/// line, inside an inline table too (`scale` for `sun = { blackbody = 5800, scale = "x" }`);
/// empty when the value does not follow a `=` on its line (an array's later line).
pub fn key_of_line(text: &str, at: usize) -> String {
    let mut at = at.min(text.len());
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let Some(eq) = text[start..at].rfind('=') else {
        return String::new();
    };
    let head = &text[start..start + eq];
    let key = head.rsplit(['{', ',']).next().unwrap_or("").trim();
    let plain = !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if plain {
        key.to_string()
    } else {
        String::new()
    }
}

#[cfg(test)]
mod tests {
    use super::{key_of_line, nearest, plain_message};

    #[test]
    fn the_key_of_a_values_line_is_found() {
        let text = "[render]\nspp = \"1024\"\nwidth = [\n  1,\n]\n";
        assert_eq!(key_of_line(text, text.find("\"1024").unwrap()), "spp");
        assert_eq!(key_of_line(text, text.find("1,").unwrap()), "");
        assert_eq!(key_of_line(text, 1), "");
        assert_eq!(key_of_line(text, text.len() + 5), "");
        let inline = "sun = { blackbody = 5800.0, scale = \"x\" }\n";
        assert_eq!(key_of_line(inline, inline.find("\"x").unwrap()), "scale");
        // a byte inside a multi-byte character steps back to its start
        let wide = "name = \"é\"";
        assert_eq!(key_of_line(wide, wide.find('é').unwrap() + 1), "name");
    }

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
        // serde writes a refused float in full decimals
        let huge = format!("invalid type: floating point `{}`, expected i64", 1e300);
        assert_eq!(
            plain_message(&huge),
            "invalid type: floating point `1e300`, expected an integer"
        );
        assert_eq!(
            plain_message("invalid type: floating point `0.5`, expected u32"),
            "invalid type: floating point `0.5`, expected a whole number ≥ 0"
        );
        assert_eq!(
            plain_message("unknown field `sppp`, expected one of `width`, `height`, `spp`"),
            "unknown field `sppp`, expected one of `width`, `height`, `spp`; did you mean `spp`?"
        );
        assert_eq!(
            plain_message("unknown field `spq`, expected `spp`"),
            "unknown field `spq`, expected `spp`"
        );
        // other messages unchanged; an out-of-range integer says its range
        assert_eq!(
            plain_message("invalid value: integer `5000000000`, expected u32"),
            "out of range: integer `5000000000`, expected an integer from 0 to 4294967295"
        );
        assert_eq!(
            plain_message("invalid type: integer `99999999999999999999` as i128, expected i64"),
            "out of range: integer `99999999999999999999`, expected an integer from -9223372036854775808 to 9223372036854775807"
        );
        assert_eq!(
            plain_message("missing field `camera`"),
            "missing field `camera`"
        );
    }
}
