//! The two optional columns that label a periodic multisine step: `multisine_base_hz` (the
//! base frequency f0 [Hz], 0 or empty on sine and random rows) and `multisine_lines` (the
//! excited lines k of f0, ascending positive integers separated by spaces, e.g. `9 11 15`;
//! empty on other rows). Both or neither; they need the `step` and `frequency_hz` labels.
//! A multisine row has `frequency_hz` 0 or empty. Every row repeats its step's values (like
//! `frequency_hz`), so any row says what drove it.

use std::path::Path;

use super::error::CsvError;

pub const MULTISINE_BASE_COLUMN: &str = "multisine_base_hz";
pub const MULTISINE_LINES_COLUMN: &str = "multisine_lines";
pub const MULTISINE_COLUMNS: [&str; 2] = [MULTISINE_BASE_COLUMN, MULTISINE_LINES_COLUMN];

/// A multisine step's label: its base frequency and excited lines.
#[derive(Debug, Clone, PartialEq)]
pub struct MultisineLabel {
    pub base_frequency_hz: f64,
    pub lines: Vec<usize>,
}

/// The `multisine_lines` cell of `lines`.
pub fn format_lines(lines: &[usize]) -> String {
    lines
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(" ")
}

/// What is wrong with `lines` as a multisine's excited lines, if anything.
pub fn lines_fault(lines: &[usize]) -> Option<&'static str> {
    if lines.is_empty() {
        Some("a multisine excites at least one line")
    } else if lines[0] == 0 {
        Some("line 0 (DC) cannot be excited")
    } else if lines.windows(2).any(|w| w[1] <= w[0]) {
        Some("lines must be strictly ascending")
    } else {
        None
    }
}

/// The multisine label of a row from its two cells (`None`: not a multisine row), checked
/// against the row's sine frequency.
pub fn parse_row(
    path: &Path,
    line: u64,
    base_cell: &str,
    lines_cell: &str,
    sine_frequency: Option<f64>,
) -> Result<Option<MultisineLabel>, CsvError> {
    let bad = |column: &'static str, cell: &str, reason: String| CsvError::BadMultisineCell {
        path: path.to_path_buf(),
        line,
        column,
        cell: cell.to_string(),
        reason,
    };
    let base = if base_cell.is_empty() {
        0.0
    } else {
        base_cell
            .parse::<f64>()
            .map_err(|_| bad(MULTISINE_BASE_COLUMN, base_cell, "not a number".to_string()))?
    };
    if !(base.is_finite() && base >= 0.0) {
        return Err(bad(
            MULTISINE_BASE_COLUMN,
            base_cell,
            "a base frequency must be a finite, non-negative number".to_string(),
        ));
    }
    if base == 0.0 {
        if !lines_cell.is_empty() {
            return Err(bad(
                MULTISINE_LINES_COLUMN,
                lines_cell,
                format!("lines are given but {MULTISINE_BASE_COLUMN} is 0 or empty"),
            ));
        }
        return Ok(None);
    }
    if let Some(f) = sine_frequency {
        return Err(bad(
            MULTISINE_BASE_COLUMN,
            base_cell,
            format!("a multisine row must have frequency_hz 0 or empty, this one has {f}"),
        ));
    }
    let lines = lines_cell
        .split_ascii_whitespace()
        .map(str::parse::<usize>)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|_| {
            bad(
                MULTISINE_LINES_COLUMN,
                lines_cell,
                "lines are non-negative integers separated by spaces".to_string(),
            )
        })?;
    if let Some(reason) = lines_fault(&lines) {
        return Err(bad(MULTISINE_LINES_COLUMN, lines_cell, reason.to_string()));
    }
    Ok(Some(MultisineLabel {
        base_frequency_hz: base,
        lines,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_parse_and_faults_name_the_column() {
        let p = Path::new("x.csv");
        let got = parse_row(p, 5, "0.5", " 9 11  15 ", None).unwrap();
        assert_eq!(
            got,
            Some(MultisineLabel {
                base_frequency_hz: 0.5,
                lines: vec![9, 11, 15]
            })
        );
        assert_eq!(format_lines(&[9, 11, 15]), "9 11 15");
        assert_eq!(parse_row(p, 5, "", "", Some(3.0)).unwrap(), None);
        assert_eq!(parse_row(p, 5, "0", "", None).unwrap(), None);
        for (base, lines, needle) in [
            ("0.5", "9 9", "ascending"),
            ("0.5", "0 3", "DC"),
            ("0.5", "", "at least one line"),
            ("0.5", "3,5", "separated by spaces"),
            ("x", "3", "not a number"),
            ("-1", "3", "non-negative"),
            ("", "3", "is 0 or empty"),
        ] {
            let e = parse_row(p, 7, base, lines, None).unwrap_err().to_string();
            assert!(e.contains("line 7") && e.contains(needle), "{e}");
        }
        let e = parse_row(p, 7, "0.5", "3", Some(2.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("frequency_hz 0 or empty"), "{e}");
    }
}
