//! Test-bench CSV export: the form in which rig data usually leaves a DAQ.
//!
//! # Contract
//!
//! A header row names the columns; all values are SI. Every data row is one sample.
//!
//! * Always required: `time_s`, `step` (record index 0, 1, 2, ...) and `frequency_hz`
//!   (excitation frequency of a stepped-sine step; `0` or empty for random excitation).
//! * [`SetupKind::BaseExcited`] (base-excited test rig) additionally requires
//!   `base_displacement_m`, `relative_displacement_m`, `mass_acceleration_mps2`.
//! * [`SetupKind::DrivePoint`] (force-driven structure, the 3-DOF example) additionally
//!   requires `relative_displacement_m`, `drive_point_displacement_m`, `force_n`.
//! * Optional, both or neither, with the labels: `multisine_base_hz` and `multisine_lines`,
//!   which label a periodic multisine step ([`multisine`] says how).
//! * Optional, all three or none, with the labels: `sweep_law`, `sweep_start_hz` and
//!   `sweep_end_hz`, which label a sine-sweep step ([`sweep`] says how).
//! * Any other [`Channel::name`] column is optional and read when present. Every cell of a
//!   present channel column must hold a finite number.
//! * Columns with other names are ignored and returned in [`CsvImport::ignored_columns`].
//!
//! The profile is decided from the header: rig if `base_displacement_m` is present,
//! drive-point if `force_n` and `drive_point_displacement_m` are present.
//!
//! Rows are grouped into records by `step`, through the step assembler of [`crate::steps`]
//! under [`StepRules::WRITTEN`](crate::steps::StepRules::WRITTEN), the code that also turns
//! bag and live samples into records. A step's rows start when the excitation changed, so
//! they include the transient. Steps must be contiguous (each new step is the previous one
//! plus one; the first may be any non-negative integer) and each step must have at least 3
//! rows. Time must increase strictly over the whole file (it counts from the start of the
//! run). Times are read by the assembler's timing rule ([`crate::steps::timing`]): each record
//! has its own sample rate; a pause or lost rows end a record (the step goes on in another,
//! with a notice naming the line); times that jitter about a uniform grid by up to a tenth of
//! an interval are read as uniform (one notice per file); a time off by more is refused.
//! Times are exact within 1e-6 relative plus the rounding of the time column when the file
//! writes time with a fixed number of decimals (e.g. `0.000100`).
//!
//! The excitation amplitude is not part of the export, so it is *estimated* on import: for a
//! sine step, `amplitude = sqrt(2) * RMS` of the driven channel (base displacement for the rig,
//! force for the drive-point profile) over the whole step after removing its mean; for a
//! sweep step, its amplitude likewise; for a
//! random record, `rms` is the RMS of the driven channel after removing its mean. Both include
//! the transient at the start of the step, so they are estimates, not the commanded values.
//!
//! [`write_csv`] writes the same contract, with full f64 precision (shortest round-trip
//! formatting), atomically (temporary file in the same directory, renamed at the end).
//!
//! Lab dialects (`;` or tab separators, decimal commas, a units row, a byte-order mark, CRLF, a
//! truncated last line) are detected from the first lines and undone before the rows are read
//! ([`dialect`]); [`CsvImport::notices`] says what was found.
//!
//! Files: `contract` (column names, required columns, the header's layout), `dialect`,
//! `multisine` (the multisine label columns), `sweep` (the sweep label columns), `read`, `rows`
//! (the rows split in place), `row_cells` (a row's cells parsed), `row_parts` (a chunk's rows
//! parsed over the cores), `row_steps` (rows into step records), `stream` (a file read chunk by chunk),
//! `import` (records labelled, checked and handed over as they are read), `number_rows` (rows
//! of numbers, a measurement file's channels, read by the same rules), `write`, `error`.
//!
//! [`SetupKind::BaseExcited`]: forcemap_math::recipe::SetupKind::BaseExcited
//! [`SetupKind::DrivePoint`]: forcemap_math::recipe::SetupKind::DrivePoint
//! [`Channel::name`]: forcemap_math::record::Channel::name

mod contract;
pub mod dialect;
mod error;
mod import;
pub mod multisine;
mod number_rows;
mod read;
mod row_cells;
mod row_parts;
mod row_steps;
mod rows;
mod stream;
pub mod sweep;
mod write;

pub use contract::{
    CsvImport, FREQUENCY_COLUMN, SAMPLE_INTERVAL_REL_TOL, STEP_COLUMN, TIME_COLUMN,
    required_columns,
};
pub use error::CsvError;
pub use multisine::{MULTISINE_BASE_COLUMN, MULTISINE_LINES_COLUMN};
pub use number_rows::{NumberRowsError, read_number_rows};
pub use read::{read_csv, read_csv_from, read_csv_reduced};
#[doc(hidden)]
pub use stream::read_csv_in_chunks;
pub use sweep::{SWEEP_END_COLUMN, SWEEP_LAW_COLUMN, SWEEP_START_COLUMN};
pub use write::write_csv;
