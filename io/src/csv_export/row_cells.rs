//! A CSV export's row parsed into numbers and labels: what a row says, read apart from the
//! rows before it (the rules that tie a row to the rows before it are the step assembly's, in
//! `row_steps`). A row's cells are read in the order the errors are reported in: its labels
//! and time here ([`parse_head`]), then the checks against the rows before, then its channel
//! values ([`parse_values`]).

use std::path::Path;

use super::contract::{FREQUENCY_COLUMN, Layout, STEP_COLUMN, TIME_COLUMN};
use super::error::CsvError;
use super::multisine::{self, MultisineLabel};
use super::rows::Rows;
use super::sweep::{self, SweepLabel};

/// A row's time and labels.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RowHead {
    /// The row's line, as the `csv` crate counts it.
    pub line: u64,
    pub time_s: f64,
    /// The rounding of the time as written.
    pub time_resolution_s: f64,
    pub step: usize,
    /// `None` stands for random excitation (0 or empty).
    pub frequency_hz: Option<f64>,
    /// A multisine's or a sweep's label (boxed: most rows have none, and a chunk's rows are
    /// held parsed).
    pub labels: Option<Box<RowLabels>>,
}

/// A row's multisine and sweep labels.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RowLabels {
    pub multisine: Option<MultisineLabel>,
    pub sweep: Option<SweepLabel>,
}

/// The time and labels of the current row of `rows`, checked cell by cell.
pub(super) fn parse_head(path: &Path, layout: &Layout, rows: &Rows) -> Result<RowHead, CsvError> {
    let line = rows.line();
    rows.check_utf8(path)?;
    let cell = |col: usize| rows.cell(col);

    let time_text = cell(layout.time_col);
    let time = parse_number(path, line, TIME_COLUMN, time_text)?;
    let step = match layout.step_col {
        Some(col) => parse_step(path, line, cell(col))?,
        None => 0,
    };
    let freq = parse_frequency(path, line, layout.freq_col.map_or(&b""[..], cell))?;
    let multisine = match layout.multisine_cols {
        Some((base_col, lines_col)) => multisine::parse_row(
            path,
            line,
            text(cell(base_col)),
            text(cell(lines_col)),
            freq,
        )?,
        None => None,
    };
    let sweep = match layout.sweep_cols {
        Some(cols) => {
            let other = if freq.is_some() {
                Some("a sine step")
            } else if multisine.is_some() {
                Some("a multisine")
            } else {
                None
            };
            sweep::parse_row(path, line, cols.map(|c| text(cell(c))), other)?
        }
        None => None,
    };
    Ok(RowHead {
        line,
        time_s: time,
        time_resolution_s: decimal_resolution(time_text),
        step,
        frequency_hz: freq,
        labels: (multisine.is_some() || sweep.is_some())
            .then(|| Box::new(RowLabels { multisine, sweep })),
    })
}

/// A sine step's frequency: `None` (random excitation) for an empty cell or 0.
pub(super) fn parse_frequency(
    path: &Path,
    line: u64,
    cell: &[u8],
) -> Result<Option<f64>, CsvError> {
    if cell.is_empty() {
        return Ok(None);
    }
    let f = parse_number(path, line, FREQUENCY_COLUMN, cell)?;
    if f < 0.0 {
        return Err(CsvError::InvalidValue {
            path: path.to_path_buf(),
            line,
            column: FREQUENCY_COLUMN.to_string(),
            cell: String::from_utf8_lossy(cell).into_owned(),
            reason: "a frequency must not be negative",
        });
    }
    Ok((f != 0.0).then_some(f))
}

/// The channel values of the current row of `rows` (on `line`), in the layout's order,
/// appended to `values`.
pub(super) fn parse_values(
    path: &Path,
    layout: &Layout,
    rows: &Rows,
    line: u64,
    values: &mut Vec<f64>,
) -> Result<(), CsvError> {
    for &(c, col) in &layout.channel_cols {
        values.push(parse_number(path, line, c.name(), rows.cell(col))?);
    }
    Ok(())
}

/// A cell of a row `Rows::check_utf8` accepted, as text.
pub(super) fn text(cell: &[u8]) -> &str {
    std::str::from_utf8(cell).unwrap_or_default()
}

pub(super) fn parse_number(
    path: &Path,
    line: u64,
    column: &str,
    cell: &[u8],
) -> Result<f64, CsvError> {
    if cell.is_empty() {
        return Err(CsvError::EmptyCell {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
        });
    }
    let lossy = || String::from_utf8_lossy(cell).into_owned();
    // What the fast parser refuses goes through `str::parse` trimmed of any Unicode
    // whitespace (as string records were; `cell` trims ASCII only), so that the same cells
    // are numbers, empty or refused as before.
    let v: f64 = match fast_float2::parse(cell) {
        Ok(v) => v,
        Err(_) => {
            let trimmed = text(cell).trim();
            if trimmed.is_empty() {
                return Err(CsvError::EmptyCell {
                    path: path.to_path_buf(),
                    line,
                    column: column.to_string(),
                });
            }
            trimmed.parse().map_err(|_| CsvError::NonNumeric {
                path: path.to_path_buf(),
                line,
                column: column.to_string(),
                cell: lossy(),
            })?
        }
    };
    if !v.is_finite() {
        return Err(CsvError::NonFinite {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
            cell: lossy(),
        });
    }
    Ok(v)
}

/// A step index: a non-negative integer (an integral float such as `3.0` is accepted).
pub(super) fn parse_step(path: &Path, line: u64, cell: &[u8]) -> Result<usize, CsvError> {
    if let Ok(s) = text(cell).parse::<usize>() {
        return Ok(s);
    }
    let v = parse_number(path, line, STEP_COLUMN, cell)?;
    if v >= 0.0 && v.fract() == 0.0 && v <= u32::MAX as f64 {
        Ok(v as usize)
    } else {
        Err(CsvError::InvalidValue {
            path: path.to_path_buf(),
            line,
            column: STEP_COLUMN.to_string(),
            cell: String::from_utf8_lossy(cell).into_owned(),
            reason: "a step index must be a non-negative integer",
        })
    }
}

/// The decimal resolution of the cell an export writes for the finite `v`
/// ([`write_f64`](super::write::write_f64)), `decimal_resolution` of that cell, from the shortest
/// digits of `v` (ryu) without writing the cell: the power of ten of its last significant
/// digit, and no coarser than 1 where the cell has no exponent (`130` -> 1, `1.3e22` -> 1e21).
pub(super) fn resolution_of(v: f64) -> f64 {
    if v == 0.0 {
        return 1.0;
    }
    let mut buffer = ryu::Buffer::new();
    let text = buffer.format_finite(v).as_bytes();
    let (mantissa, exponent) = match text.iter().position(|&b| b == b'e' || b == b'E') {
        Some(i) => (
            &text[..i],
            self::text(&text[i + 1..]).parse::<i32>().unwrap_or(0),
        ),
        None => (text, 0),
    };
    let (whole, fraction) = match mantissa.iter().position(|&b| b == b'.') {
        Some(i) => (&mantissa[..i], &mantissa[i + 1..]),
        None => (mantissa, &b""[..]),
    };
    let trailing_zeros = |digits: &[u8]| digits.iter().rev().take_while(|&&b| b == b'0').count();
    let fraction = &fraction[..fraction.len() - trailing_zeros(fraction)];
    let last_digit = if fraction.is_empty() {
        exponent + trailing_zeros(whole) as i32
    } else {
        exponent - fraction.len() as i32
    };
    let a = v.abs();
    10f64.powi(if (1e-5..1e16).contains(&a) {
        last_digit.min(0)
    } else {
        last_digit
    })
}

/// The decimal resolution a number was written with: `0.000100` -> 1e-6, `1.5e-3` -> 1e-4.
pub(super) fn decimal_resolution(text: &[u8]) -> f64 {
    let (mantissa, exponent) = match text.iter().position(|&b| b == b'e' || b == b'E') {
        Some(i) => (
            &text[..i],
            self::text(&text[i + 1..]).parse::<i32>().unwrap_or(0),
        ),
        None => (text, 0),
    };
    let decimals = mantissa.iter().position(|&b| b == b'.').map_or(0, |i| {
        mantissa[i + 1..]
            .iter()
            .filter(|b| b.is_ascii_digit())
            .count()
    });
    10f64.powi(exponent - decimals as i32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `decimal_resolution` of the cell an export writes for `v`.
    fn of_the_cell(v: f64) -> f64 {
        let mut cell = String::new();
        super::super::write::write_f64(&mut cell, v);
        decimal_resolution(cell.as_bytes())
    }

    #[test]
    fn the_resolution_of_a_number_is_that_of_its_cell() {
        let mut values = vec![
            0.0, -0.0, 1.0, 130.0, -130.0, 0.5, 1.25, 1e-5, 9.99e-6, 1e16,
        ];
        values.extend([
            1.3e22,
            3e20,
            1e15,
            9.999999999999998e15,
            1.5e-7,
            f64::MIN_POSITIVE,
        ]);
        values.extend([
            f64::MAX,
            f64::MIN,
            5e-324,
            123_456_789.0,
            0.1 + 0.2,
            1e21,
            100.0,
        ]);
        // Times as a clock writes them: steps of 0.01 s, 1 us, 1/3 s over long runs.
        for k in 0..20_000_i32 {
            let k = f64::from(k);
            values.extend([k * 0.01, k * 1e-6, k / 3.0, k * 1e3, 1e7 + k * 1e-4]);
        }
        for v in values {
            assert_eq!(
                resolution_of(v).to_bits(),
                of_the_cell(v).to_bits(),
                "{v:e}"
            );
        }
    }

    proptest::proptest! {
        #[test]
        fn any_finite_number_has_the_resolution_of_its_cell(bits in proptest::num::u64::ANY) {
            let v = f64::from_bits(bits);
            if v.is_finite() {
                proptest::prop_assert_eq!(resolution_of(v).to_bits(), of_the_cell(v).to_bits());
            }
        }

        #[test]
        fn a_decimal_number_has_the_resolution_of_its_cell(
            m in -10_000_000_i64..10_000_000,
            e in -30_i32..30,
        ) {
            let v = m as f64 * 10f64.powi(e);
            proptest::prop_assert_eq!(resolution_of(v).to_bits(), of_the_cell(v).to_bits());
        }
    }
}
