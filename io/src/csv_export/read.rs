//! Reading the CSV contract: the dialect undone, the header's layout, the rows parsed and
//! grouped into records (`row_steps`: the rules of cells, lines and columns, then the step
//! assembler of [`crate::steps`], whose rules a step's samples share with bag and live samples,
//! their timing among them: each record its own sample rate, a pause or lost rows ending a
//! record, jittered times read as uniform), then what only an export needs (`import`): the
//! labels checked against the drive, and the excitation amplitude estimated from the data since
//! the export carries none.

use std::io;
use std::path::Path;

use super::contract::{CsvImport, Layout};
use super::dialect;
use super::error::{CsvError, csv_error};
use super::import::{Import, Keep};
use super::row_parts::PartRule;
use super::row_steps::RowSteps;
use super::stream::{CHUNK_BYTES, read_csv_in_chunks, read_in_chunks};
use forcemap_math::record::Record;

/// Reads a test-bench CSV export (see the module documentation for the contract), chunk by
/// chunk: the file's bytes in memory are a chunk, not the file.
pub fn read_csv(path: impl AsRef<Path>) -> Result<CsvImport, CsvError> {
    read_csv_in_chunks(path.as_ref(), CHUNK_BYTES)
}

/// [`read_csv`] with each record handed to `keep` as soon as it is read (a labelled export's;
/// an unlabelled export's once the whole run is read and cut into steps): the import's records
/// are those `keep` returns. For an analysis that streams a long export: what it does not keep,
/// the reading does not hold.
pub fn read_csv_reduced(
    path: impl AsRef<Path>,
    mut keep: impl FnMut(Record) -> Option<Record>,
) -> Result<CsvImport, CsvError> {
    read_in_chunks(
        path.as_ref(),
        CHUNK_BYTES,
        PartRule::of_machine(),
        &mut keep,
    )
}

/// Reads the CSV contract from any reader; `path` is used in error messages only.
pub fn read_csv_from<R: io::Read>(mut reader: R, path: &Path) -> Result<CsvImport, CsvError> {
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|source| CsvError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
    read_bytes(&bytes, path, PartRule::of_machine(), &mut Some)
}

/// [`read_csv_from`] of a file's `bytes`, its rows split over the cores by `rule`, each record
/// handed to `keep`.
pub(super) fn read_bytes(
    bytes: &[u8],
    path: &Path,
    rule: PartRule,
    keep: Keep,
) -> Result<CsvImport, CsvError> {
    let p = || path.to_path_buf();
    // The dialect is detected from the first lines and undone here (see `dialect`).
    let prepared = dialect::prepare(bytes, path)?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::Headers)
        .flexible(false)
        .delimiter(prepared.dialect.separator)
        .from_reader(&prepared.text[..]);
    let skip_units_row = prepared.dialect.units.is_some();
    let header = rdr.headers().map_err(|e| csv_error(path, e))?.clone();
    if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
        return Err(CsvError::Empty { path: p() });
    }
    let layout = Layout::of_header(&header, path)?;
    // The rows after the header, split in place (`rows`): no allocation per row.
    let after_header = rdr.position();
    let mut read = RowSteps::new(path, &layout, skip_units_row, rule);
    read.text_rows(
        &prepared.text,
        prepared.dialect.separator,
        header.len(),
        after_header.byte() as usize,
        after_header.line(),
        true,
    )?;
    let (steps, unlabelled_times) = read.finish()?;
    let mut import = Import::new(layout, keep);
    import.records_read(steps);
    import.finish(path, &unlabelled_times, prepared.notices)
}
