//! Comma-separated tables of numbers (spectral data: a wavelength column, then value columns),
//! read by column name. Plain parsing only: units and meaning belong to the caller. Errors
//! give lines and cell numbers, never the file's contents (a scene may name any file).

/// A malformed table: the 1-based line and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct CsvError {
    /// 1-based line of the problem.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// The first column and the column named `column` (a header cell after the first) of a CSV
/// text, as numbers; blank lines are skipped.
pub fn column(text: &str, column: &str) -> Result<(Vec<f64>, Vec<f64>), CsvError> {
    let at = |line: usize, message: String| CsvError { line, message };
    let mut lines = text.lines().enumerate();
    let header: Vec<&str> = match lines.next() {
        Some((_, h)) => h.split(',').map(str::trim).collect(),
        None => return Err(at(1, "empty CSV; expected a header row".into())),
    };
    let Some(ci) = header.iter().position(|h| *h == column).filter(|&i| i > 0) else {
        return Err(at(
            1,
            // the file's contents are not quoted: a scene may name any file
            format!(
                "no column {:?}; the header names {} value columns after the wavelength",
                crate::limits::quote(column),
                header.len().saturating_sub(1)
            ),
        ));
    };
    let (mut ws, mut vs) = (Vec::new(), Vec::new());
    for (i, l) in lines {
        if l.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = l.split(',').map(str::trim).collect();
        let cell = |k: usize| -> Result<f64, CsvError> {
            let c = cells.get(k).ok_or_else(|| {
                at(
                    i + 1,
                    format!(
                        "row has {} cells; column {column:?} is cell {}",
                        cells.len(),
                        k + 1
                    ),
                )
            })?;
            c.parse::<f64>()
                .map_err(|_| at(i + 1, format!("cell {} is not a number", k + 1)))
        };
        ws.push(cell(0)?);
        vs.push(cell(ci)?);
    }
    Ok((ws, vs))
}
