//! JSON files of numbers as files of columns, as labs export them from Python or MATLAB
//! (`json.dump`, `jsonencode`): the top level is an object; each member that is an array of
//! numbers is a column named as the member, each array of rows of numbers (n rows of k, n > k)
//! gives k columns of that name (picked with `column: 1..k`), and every other member (a number,
//! a string such as a unit, a nested object) is not a column. JSON carries no units for its
//! arrays: the map gives them.

use std::path::{Path, PathBuf};

use serde_json::Value;

use super::{ColumnFile, ColumnInfo, RawValues};
use crate::table::TableError;

const FORMAT: &str = "JSON";

pub struct JsonColumns {
    path: PathBuf,
    columns: Vec<ColumnInfo>,
    values: Vec<Vec<f64>>,
}

/// The numbers of a JSON array, or the position (1-based) of its first element that is not a
/// number. `null` (what Python's `json` writes for NaN with `allow_nan=False` off) is NaN, so
/// that the finiteness check names it.
fn numbers(array: &[Value]) -> Result<Vec<f64>, usize> {
    array
        .iter()
        .enumerate()
        .map(|(i, v)| match v {
            Value::Number(n) => n.as_f64().ok_or(i + 1),
            Value::Null => Ok(f64::NAN),
            _ => Err(i + 1),
        })
        .collect()
}

impl JsonColumns {
    pub fn open(path: &Path) -> Result<JsonColumns, TableError> {
        let bytes = std::fs::read(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            action: "cannot open for reading",
            source,
        })?;
        JsonColumns::from_bytes(&bytes, path)
    }

    /// The columns of a JSON document's `bytes` (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<JsonColumns, TableError> {
        let format_error = |message: String| TableError::Format {
            path: path.to_path_buf(),
            format: FORMAT,
            message,
        };
        let doc: Value = serde_json::from_slice(bytes).map_err(|e| {
            format_error(format!(
                "not readable JSON: {e} (line {}, column {})",
                e.line(),
                e.column()
            ))
        })?;
        let Value::Object(members) = doc else {
            return Err(format_error(
                "the top level is not an object of named arrays".into(),
            ));
        };
        let mut columns = Vec::new();
        let mut values = Vec::new();
        for (name, member) in &members {
            let Value::Array(items) = member else {
                continue;
            };
            if items.len() >= 2 && items.iter().all(Value::is_array) {
                // Rows of k numbers each: k columns.
                let rows: Vec<Vec<f64>> = items
                    .iter()
                    .enumerate()
                    .map(|(i, row)| {
                        numbers(row.as_array().map_or(&[][..], Vec::as_slice)).map_err(|j| {
                            format_error(format!(
                                "'{name}': row {} element {j} is not a number",
                                i + 1
                            ))
                        })
                    })
                    .collect::<Result<_, _>>()?;
                let k = rows[0].len();
                if let Some(i) = rows.iter().position(|r| r.len() != k) {
                    return Err(format_error(format!(
                        "'{name}': row {} has {} numbers, row 1 has {k}",
                        i + 1,
                        rows[i].len()
                    )));
                }
                if rows.len() > k {
                    for j in 0..k {
                        columns.push(info(name, columns.len() + 1, (k > 1).then_some(j + 1)));
                        values.push(rows.iter().map(|r| r[j]).collect());
                    }
                }
            } else if items.len() >= 2 && items.iter().all(|v| v.is_number() || v.is_null()) {
                let v = numbers(items)
                    .map_err(|j| format_error(format!("'{name}': element {j} is not a number")))?;
                columns.push(info(name, columns.len() + 1, None));
                values.push(v);
            }
        }
        Ok(JsonColumns {
            path: path.to_path_buf(),
            columns,
            values,
        })
    }
}

fn info(name: &str, position: usize, matrix_column: Option<usize>) -> ColumnInfo {
    ColumnInfo {
        name: Some(name.to_string()),
        group: None,
        position,
        matrix_column,
        unit: None,
        time_base: None,
    }
}

impl ColumnFile for JsonColumns {
    fn format(&self) -> &'static str {
        FORMAT
    }

    fn columns(&self) -> &[ColumnInfo] {
        &self.columns
    }

    fn read(&mut self, picks: &[(usize, bool)]) -> Result<Vec<RawValues>, TableError> {
        super::finite_columns(&self.path, FORMAT, &self.columns, &self.values, picks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn open_text(text: &str) -> Result<JsonColumns, TableError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.json");
        std::fs::write(&path, text).unwrap();
        JsonColumns::open(&path)
    }

    /// A matrix of rows gives one column per position, a named array one column; scalars and
    /// strings are not columns.
    #[test]
    fn rows_and_arrays_become_columns() {
        let mut f = open_text(
            r#"{"data": [[0, 1.5, 10], [0.5, 2.5, 20], [1, 3.5, 30], [1.5, 4.5, 40]],
                "dt": 0.5, "units": "in", "force": [1, 2, 3, 4]}"#,
        )
        .unwrap();
        let labels: Vec<String> = f.columns().iter().map(ColumnInfo::label).collect();
        assert_eq!(
            labels,
            [
                "'data' column 1",
                "'data' column 2",
                "'data' column 3",
                "'force'"
            ]
        );
        let v = f.read(&[(1, false), (3, false)]).unwrap();
        assert_eq!(v[0], RawValues::Numbers(vec![1.5, 2.5, 3.5, 4.5]));
        assert_eq!(v[1], RawValues::Numbers(vec![1.0, 2.0, 3.0, 4.0]));
    }

    /// Bad input names the member, the row and the element.
    #[test]
    fn bad_input_is_named() {
        let e = open_text(r#"{"data": [[0, 1], [0.5, "x"], [1, 2]]}"#)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("'data': row 2 element 2 is not a number"), "{e}");
        let e = open_text(r#"{"data": [[0, 1], [0.5], [1, 2]]}"#)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("row 2 has 1 numbers, row 1 has 2"), "{e}");
        let e = open_text("[1, 2]").err().unwrap().to_string();
        assert!(e.contains("not an object"), "{e}");
        let e = open_text("{\"a\": [1, 2,").err().unwrap().to_string();
        assert!(e.contains("not readable JSON"), "{e}");
        let mut f = open_text(r#"{"x": [1, null, 3]}"#).unwrap();
        let e = f.read(&[(0, false)]).err().unwrap().to_string();
        assert!(e.contains("'x': element 2 is not a finite number"), "{e}");
    }
}
