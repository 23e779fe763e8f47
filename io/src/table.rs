//! Channels read from a measurement file (MDF4, TDMS, a file of columns through a map) as one
//! table of named columns, turned into records by the CSV contract's reader: the rows go
//! through the same checks and step assembly as a CSV export's, so that the same run gives the
//! same records from either.
//!
//! The table's rows go to the contract's reader as numbers, a block at a time
//! ([`read_number_rows`]), each read as the cell an export would write for it. What the reader
//! says of a row (errors, warnings, notices) names the row's line in the file where the file
//! has lines (text), else its sample: the reader's `line k + 2` is sample `k` (the header is
//! line 1).

use std::path::{Path, PathBuf};

use forcemap_math::record::{Channel, Record};

use crate::csv_export::{
    CsvImport, FREQUENCY_COLUMN, NumberRowsError, STEP_COLUMN, TIME_COLUMN, read_number_rows,
};

/// The contract column a channel of a measurement file stands for, by its name: a forcemap
/// channel name (`force_n`, `base_displacement_m`, ...), `time_s`, `step` or `frequency_hz`.
/// Other channels are not read. One function, so that a channel map (topic/field/scale) can
/// take its place later.
pub fn contract_column(name: &str) -> Option<&'static str> {
    [TIME_COLUMN, STEP_COLUMN, FREQUENCY_COLUMN]
        .into_iter()
        .find(|c| *c == name)
        .or_else(|| Channel::from_name(name).map(Channel::name))
}

/// Errors of reading a measurement file into records.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    #[error("{}: {action}: {source}", path.display())]
    Io {
        path: PathBuf,
        action: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// The file's structure: what is wrong and where (segment, block, channel).
    #[error("{}: {format}: {message}", path.display())]
    Format {
        path: PathBuf,
        format: &'static str,
        message: String,
    },
    /// The samples, by the rules of the CSV contract, named by the file's lines or samples.
    #[error("{message} ({format} data)")]
    Rows {
        format: &'static str,
        message: String,
    },
}

/// The file's line (1-based) of each row of a table, kept as runs of consecutive lines: a text
/// file's rows follow one another but where a comment or blank line comes between, so a long
/// file's lines take a few entries, not one a row.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RowLines {
    /// Each run's first row and its line, rows ascending.
    runs: Vec<(usize, u64)>,
    rows: usize,
}

impl RowLines {
    /// The next row is on `line`.
    pub fn push(&mut self, line: u64) {
        let continues = self
            .runs
            .last()
            .is_some_and(|&(row, first)| first + (self.rows - row) as u64 == line);
        if !continues {
            self.runs.push((self.rows, line));
        }
        self.rows += 1;
    }

    /// The line of `row`, if the table has it.
    pub fn get(&self, row: usize) -> Option<u64> {
        if row >= self.rows {
            return None;
        }
        let (first_row, line) = self.runs[self.runs.partition_point(|&(r, _)| r <= row) - 1];
        Some(line + (row - first_row) as u64)
    }

    pub fn len(&self) -> usize {
        self.rows
    }

    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// The lines of rows `from..to` (clamped to the rows held), run by run.
    pub fn range(&self, from: usize, to: usize) -> RowLines {
        let to = to.min(self.rows);
        let mut out = RowLines::default();
        for (i, &(start, line)) in self.runs.iter().enumerate() {
            let end = self.runs.get(i + 1).map_or(self.rows, |r| r.0);
            let (a, b) = (start.max(from), end.min(to));
            if a < b {
                out.runs.push((a - from, line + (a - start) as u64));
                out.rows += b - a;
            }
        }
        out
    }

    /// Every row's line, in order.
    pub fn iter(&self) -> impl Iterator<Item = u64> + '_ {
        (0..self.rows).map(|r| self.get(r).expect("a row held"))
    }
}

impl FromIterator<u64> for RowLines {
    fn from_iter<I: IntoIterator<Item = u64>>(lines: I) -> RowLines {
        let mut out = RowLines::default();
        for l in lines {
            out.push(l);
        }
        out
    }
}

/// Where a table's rows are in its file: the file's line of each sample, or none (binary
/// formats, whose rows are named as samples).
#[derive(Debug, Clone, Copy)]
pub enum RowPlaces<'a> {
    Lines(&'a RowLines),
    Samples,
}

impl RowPlaces<'_> {
    /// `text` with each `line N` (and `lines N-M`) of the CSV text (N >= 2: sample N - 2)
    /// named as its place in the file: `line L` of the file, or `sample N - 2`.
    pub fn rename(self, text: &str) -> String {
        let place = |n: u64| -> Option<(String, u64)> {
            let sample = n.checked_sub(2)?;
            Some(match self {
                RowPlaces::Lines(lines) => match lines.get(sample as usize) {
                    Some(l) => ("line".into(), l),
                    None => ("sample".into(), sample),
                },
                RowPlaces::Samples => ("sample".into(), sample),
            })
        };
        let number = |s: &str| {
            let digits = s.bytes().take_while(u8::is_ascii_digit).count();
            s[..digits].parse::<u64>().ok().map(|n| (n, digits))
        };
        let mut out = String::with_capacity(text.len());
        let mut rest = text;
        while let Some(at) = rest.find("line") {
            out.push_str(&rest[..at]);
            let (plural, after) = match &rest[at + 4..] {
                a if a.starts_with("s ") => (true, &a[2..]),
                a if a.starts_with(' ') => (false, &a[1..]),
                a => {
                    out.push_str("line");
                    rest = a;
                    continue;
                }
            };
            let first = number(after).and_then(|(n, d)| place(n).map(|p| (p, d)));
            let second = plural
                .then(|| first.as_ref().map(|(_, d)| &after[*d..]))
                .flatten()
                .and_then(|a| a.strip_prefix('-'))
                .and_then(|a| number(a).and_then(|(n, d)| place(n).map(|p| (p, d))));
            match (first, second) {
                (Some(((word, a), _)), Some(((_, b), d2))) if plural => {
                    let used = after.find('-').map_or(0, |i| i + 1) + d2;
                    out.push_str(&format!("{word}s {a}-{b}"));
                    rest = &after[used..];
                }
                (Some(((word, a), d)), None) if !plural => {
                    out.push_str(&format!("{word} {a}"));
                    rest = &after[d..];
                }
                _ => {
                    out.push_str(if plural { "lines " } else { "line " });
                    rest = after;
                }
            }
        }
        out.push_str(rest);
        out
    }
}

/// Checks the columns a table hands to the CSV contract's reader, by name and number of
/// samples, before any is read: at least one, all as long as the first.
pub fn check_columns(
    names: &[&str],
    lengths: &[usize],
    path: &Path,
    format: &'static str,
) -> Result<(), TableError> {
    let (Some(first), Some(&n)) = (names.first(), lengths.first()) else {
        return Err(TableError::Format {
            path: path.to_path_buf(),
            format,
            message: "no channel with a forcemap name (time_s, step, frequency_hz, \
                      force_n, base_displacement_m, ...)"
                .to_string(),
        });
    };
    if let Some((name, len)) = names.iter().zip(lengths).find(|(_, l)| **l != n) {
        return Err(TableError::Format {
            path: path.to_path_buf(),
            format,
            message: format!(
                "channel '{name}' has {len} samples but '{first}' has {n}; the channels must \
                 share one time base"
            ),
        });
    }
    Ok(())
}

/// The records of a table's rows (the columns `names`, which `fill` appends a block of rows at
/// a time: [`read_number_rows`]), each handed to `keep` as it is read; what the reader says
/// of a row names it by `places`.
pub fn read_table_rows(
    path: &Path,
    format: &'static str,
    places: RowPlaces,
    names: &[&str],
    keep: impl FnMut(Record) -> Option<Record>,
    fill: impl FnMut(&mut Vec<f64>) -> Result<usize, TableError>,
) -> Result<CsvImport, TableError> {
    let rename = |e: NumberRowsError<TableError>| match e {
        NumberRowsError::Rows(e) => TableError::Rows {
            format,
            message: places.rename(&e.to_string()),
        },
        NumberRowsError::Source(e) => e,
    };
    let mut import = read_number_rows(path, names, keep, fill).map_err(rename)?;
    for m in import.warnings.iter_mut().chain(import.notices.iter_mut()) {
        *m = places.rename(m);
    }
    Ok(import)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_map_to_the_contract() {
        assert_eq!(contract_column("force_n"), Some("force_n"));
        assert_eq!(contract_column("time_s"), Some("time_s"));
        assert_eq!(contract_column("Force"), None);
    }

    #[test]
    fn unequal_columns_are_refused_by_name() {
        let p = Path::new("x.tdms");
        let e = check_columns(&["time_s", "force_n"], &[3, 2], p, "TDMS")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("'force_n' has 2 samples but 'time_s' has 3"),
            "{e}"
        );
        let e = check_columns(&[], &[], p, "TDMS").unwrap_err().to_string();
        assert!(e.contains("no channel with a forcemap name"), "{e}");
    }

    #[test]
    fn row_lines_are_kept_as_runs() {
        let lines = [3, 4, 5, 7, 8, 20, 21, 22, 23, 30];
        let kept: RowLines = lines.into_iter().collect();
        assert_eq!(kept.runs.len(), 4);
        assert_eq!(kept.len(), lines.len());
        assert_eq!(kept.iter().collect::<Vec<_>>(), lines);
        for (row, &line) in lines.iter().enumerate() {
            assert_eq!(kept.get(row), Some(line));
        }
        assert_eq!(kept.get(lines.len()), None);
        assert_eq!(
            kept.range(2, 7).iter().collect::<Vec<_>>(),
            [5, 7, 8, 20, 21]
        );
        assert_eq!(kept.range(8, 99).iter().collect::<Vec<_>>(), [23, 30]);
        for from in 0..=lines.len() {
            for to in from..=lines.len() + 1 {
                let part = kept.range(from, to);
                let direct: RowLines = lines[from..to.min(lines.len())].iter().copied().collect();
                assert_eq!(part, direct, "{from}..{to}");
            }
        }
        assert!(RowLines::default().get(0).is_none());
    }

    #[test]
    fn rows_are_named_by_their_place_in_the_file() {
        let lines: RowLines = [7, 8, 10].into_iter().collect();
        let text = RowPlaces::Lines(&lines).rename(
            "f.txt: line 4, column 'time_s': time 1 s does not increase (line 3 has 2 s); line 1",
        );
        assert_eq!(
            text,
            "f.txt: line 10, column 'time_s': time 1 s does not increase (line 8 has 2 s); line 1"
        );
        assert_eq!(
            RowPlaces::Samples.rename("line 2 and line 12: breaks; lines 3; multiline"),
            "sample 0 and sample 10: breaks; lines 3; multiline"
        );
        assert_eq!(
            RowPlaces::Lines(&lines).rename("f.txt: step 2, lines 3-4: 2 rows left out"),
            "f.txt: step 2, lines 8-10: 2 rows left out"
        );
    }
}
