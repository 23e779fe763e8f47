//! MATLAB level-5 MAT files as files of columns: each numeric vector variable is a column
//! named as the variable, each matrix of n rows by k columns (n > k) gives k columns of that
//! name (picked with `column: 1..k`); scalars, complex and empty variables are not columns.
//! MAT files carry no units: the map gives them.

use std::path::{Path, PathBuf};

use super::{ColumnFile, ColumnInfo, RawValues};
use crate::table::TableError;

const FORMAT: &str = "MAT";

pub struct MatColumns {
    path: PathBuf,
    columns: Vec<ColumnInfo>,
    values: Vec<Vec<f64>>,
}

/// The real values of a numeric array as f64, or `None` for a complex one.
fn real_values(data: &matfile::NumericData) -> Option<Vec<f64>> {
    use matfile::NumericData as N;
    macro_rules! as_f64 {
        ($real:expr, $imag:expr) => {
            $imag
                .is_none()
                .then(|| $real.iter().map(|&v| v as f64).collect())
        };
    }
    match data {
        N::Int8 { real, imag } => as_f64!(real, imag),
        N::UInt8 { real, imag } => as_f64!(real, imag),
        N::Int16 { real, imag } => as_f64!(real, imag),
        N::UInt16 { real, imag } => as_f64!(real, imag),
        N::Int32 { real, imag } => as_f64!(real, imag),
        N::UInt32 { real, imag } => as_f64!(real, imag),
        N::Int64 { real, imag } => as_f64!(real, imag),
        N::UInt64 { real, imag } => as_f64!(real, imag),
        N::Single { real, imag } => as_f64!(real, imag),
        N::Double { real, imag } => as_f64!(real, imag),
    }
}

impl MatColumns {
    pub fn open(path: &Path) -> Result<MatColumns, TableError> {
        let file = std::fs::File::open(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            action: "cannot open for reading",
            source,
        })?;
        let mat = matfile::MatFile::parse(std::io::BufReader::new(file)).map_err(|e| {
            TableError::Format {
                path: path.to_path_buf(),
                format: FORMAT,
                message: format!("not a readable MAT file: {e}"),
            }
        })?;
        let mut columns = Vec::new();
        let mut values = Vec::new();
        for array in mat.arrays() {
            let size = array.size();
            let Some(real) = real_values(array.data()) else {
                continue;
            };
            let (rows, cols) = match size.as_slice() {
                [r, c] => (*r, *c),
                _ => continue,
            };
            // Column-major: element (i, j) is at j * rows + i.
            if rows.min(cols) == 1 && rows.max(cols) >= 2 {
                columns.push(info(array.name(), columns.len() + 1, None));
                values.push(real);
            } else if rows > cols && cols >= 2 {
                for j in 0..cols {
                    columns.push(info(array.name(), columns.len() + 1, Some(j + 1)));
                    values.push(real[j * rows..(j + 1) * rows].to_vec());
                }
            }
        }
        Ok(MatColumns {
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

impl ColumnFile for MatColumns {
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
