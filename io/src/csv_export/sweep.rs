//! The three optional columns that label a sine-sweep step: `sweep_law` (`linear` or `log`;
//! empty on sine, random and multisine rows), `sweep_start_hz` and `sweep_end_hz` (the
//! frequency at the step's first sample and at its end [Hz]; 0 or empty on other rows). All
//! three or none; they need the `step` and `frequency_hz` labels. A sweep row has
//! `frequency_hz` 0 or empty. The step is the sweep: it starts at phase 0 at its first sample
//! and lasts the step's samples over the sample rate; its amplitude is estimated on import as
//! `sqrt(2) * RMS` of the driven channel (like a sine step's). Every row repeats its step's
//! values, so any row says what drove it.

use std::path::Path;

use forcemap_math::phasor::SweepKind;

use super::error::CsvError;

pub const SWEEP_LAW_COLUMN: &str = "sweep_law";
pub const SWEEP_START_COLUMN: &str = "sweep_start_hz";
pub const SWEEP_END_COLUMN: &str = "sweep_end_hz";
pub const SWEEP_COLUMNS: [&str; 3] = [SWEEP_LAW_COLUMN, SWEEP_START_COLUMN, SWEEP_END_COLUMN];

/// A sweep step's label: its law and its start and end frequencies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepLabel {
    pub kind: SweepKind,
    pub start_frequency_hz: f64,
    pub end_frequency_hz: f64,
}

/// The `sweep_law` cell of `kind`.
pub fn law_name(kind: SweepKind) -> &'static str {
    match kind {
        SweepKind::Linear => "linear",
        SweepKind::Logarithmic => "log",
    }
}

/// The sweep label of a row from its three cells (`None`: not a sweep row), checked against
/// the row's sine frequency and multisine label.
pub fn parse_row(
    path: &Path,
    line: u64,
    cells: [&str; 3],
    other_label: Option<&'static str>,
) -> Result<Option<SweepLabel>, CsvError> {
    let bad = |column: &'static str, cell: &str, reason: String| CsvError::BadSweepCell {
        path: path.to_path_buf(),
        line,
        column,
        cell: cell.to_string(),
        reason,
    };
    let [law, start, end] = cells;
    let number = |column: &'static str, cell: &str| -> Result<f64, CsvError> {
        if cell.is_empty() {
            return Ok(0.0);
        }
        let v = cell
            .parse::<f64>()
            .map_err(|_| bad(column, cell, "not a number".to_string()))?;
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(bad(
                column,
                cell,
                "a frequency must be a finite, non-negative number".to_string(),
            ))
        }
    };
    let (f0, f1) = (
        number(SWEEP_START_COLUMN, start)?,
        number(SWEEP_END_COLUMN, end)?,
    );
    if law.is_empty() {
        if f0 != 0.0 || f1 != 0.0 {
            return Err(bad(
                SWEEP_LAW_COLUMN,
                law,
                "sweep frequencies are given but the law is empty (linear or log)".to_string(),
            ));
        }
        return Ok(None);
    }
    let kind = match law {
        "linear" => SweepKind::Linear,
        "log" => SweepKind::Logarithmic,
        _ => {
            return Err(bad(
                SWEEP_LAW_COLUMN,
                law,
                "a sweep law is 'linear' or 'log'".to_string(),
            ));
        }
    };
    for (column, cell, f) in [(SWEEP_START_COLUMN, start, f0), (SWEEP_END_COLUMN, end, f1)] {
        if f <= 0.0 {
            return Err(bad(
                column,
                cell,
                "a sweep row needs positive start and end frequencies".to_string(),
            ));
        }
    }
    if let Some(other) = other_label {
        return Err(bad(
            SWEEP_LAW_COLUMN,
            law,
            format!("a sweep row must not be {other} as well"),
        ));
    }
    Ok(Some(SweepLabel {
        kind,
        start_frequency_hz: f0,
        end_frequency_hz: f1,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_parse_and_faults_name_the_column() {
        let p = Path::new("x.csv");
        assert_eq!(
            parse_row(p, 3, ["log", "1.6", "3.4"], None).unwrap(),
            Some(SweepLabel {
                kind: SweepKind::Logarithmic,
                start_frequency_hz: 1.6,
                end_frequency_hz: 3.4
            })
        );
        assert_eq!(parse_row(p, 3, ["", "", "0"], None).unwrap(), None);
        for (cells, other, needle) in [
            (["cubic", "1", "2"], None, "'linear' or 'log'"),
            (["", "1", "2"], None, "law is empty"),
            (["linear", "0", "2"], None, "positive start and end"),
            (["linear", "x", "2"], None, "not a number"),
            (
                ["linear", "1", "2"],
                Some("a sine step"),
                "a sine step as well",
            ),
        ] {
            let e = parse_row(p, 7, cells, other).unwrap_err().to_string();
            assert!(e.contains(needle) && e.contains("line 7"), "{cells:?}: {e}");
        }
    }
}
