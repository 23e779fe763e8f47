//! What only an export needs once its rows are records (`row_steps`), done record by record as
//! the rows arrive: the labels checked against the drive (step by step, [`LabelCheck`]), the
//! excitation estimated from the data since the export carries none, and each record handed to
//! the caller, who keeps it or not. An export without labels is one run, cut into steps where
//! its drive changes once all of it is read.

use std::path::Path;

use super::contract::{CsvImport, Layout, TIME_COLUMN};
use super::error::CsvError;
use super::multisine::MultisineLabel;
use super::row_steps::ReadStep;
use super::sweep::SweepLabel;
use crate::steps::label_check::LabelCheck;
use crate::steps::timing::JitterSummary;
use crate::steps::unlabelled::split_parts;
use crate::steps::{estimated_excitation, rms_about_mean, sine_amplitude_from_rms};
use forcemap_math::phasor::SweepLaw;
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::segment::SegmentOptions;

/// What the caller does with each record: keeps what it returns.
pub type Keep<'k> = &'k mut dyn FnMut(Record) -> Option<Record>;

/// The records of an export as they are read, and what is said about them.
pub(super) struct Import<'k> {
    layout: Layout,
    keep: Keep<'k>,
    /// Records kept.
    records: Vec<Record>,
    /// The timing rule's notices of the steps, and its jitter over all of them.
    step_notices: Vec<String>,
    jitter: JitterSummary,
    /// The labels' check (a labelled export), or the run's records until the end (without
    /// labels).
    check: Option<LabelCheck>,
    unlabelled: Vec<ReadStep>,
}

impl<'k> Import<'k> {
    pub fn new(layout: Layout, keep: Keep<'k>) -> Import<'k> {
        let labelled = layout.step_col.is_some();
        let driven = layout.profile.driven_channel();
        Import {
            layout,
            keep,
            records: Vec::new(),
            step_notices: Vec::new(),
            jitter: JitterSummary::default(),
            check: labelled.then(|| LabelCheck::new(driven, &SegmentOptions::default())),
            unlabelled: Vec::new(),
        }
    }

    /// The records read since the last call, in file order.
    pub fn records_read(&mut self, steps: Vec<ReadStep>) {
        for s in &steps {
            self.jitter.add(s.assembled.timing.jitter.as_ref());
            self.step_notices.extend(s.notices.iter().cloned());
        }
        let Some(check) = &mut self.check else {
            self.unlabelled.extend(steps);
            return;
        };
        // The segmenter knows sines and the rest: a multisine or sweep label is not checked by
        // it.
        check.push_all(
            steps
                .iter()
                .filter(|s| s.multisine.is_none() && s.sweep.is_none())
                .map(|s| (&s.assembled.record, s.assembled.label, s.frequency)),
        );
        let driven = self.layout.profile.driven_channel();
        for s in steps {
            let ReadStep {
                frequency,
                multisine,
                sweep,
                assembled,
                ..
            } = s;
            let record = with_excitation(assembled.record, frequency, multisine, sweep, driven);
            self.records.extend((self.keep)(record));
        }
    }

    /// The import, after the file's `notices`; `unlabelled_times`: the rows' times of an export
    /// without labels.
    pub fn finish(
        mut self,
        path: &Path,
        unlabelled_times: &[f64],
        mut notices: Vec<String>,
    ) -> Result<CsvImport, CsvError> {
        notices.append(&mut self.step_notices);
        if let Some(n) = self.jitter.notice() {
            notices.push(format!("{}: column '{TIME_COLUMN}': {n}", path.display()));
        }
        let warnings = match self.check.take() {
            Some(check) => check.finish(),
            None => {
                self.split_unlabelled(path, unlabelled_times)?;
                Vec::new()
            }
        };
        Ok(CsvImport {
            records: self.records,
            ignored_columns: self.layout.ignored_columns,
            kind: self.layout.profile,
            warnings,
            notices,
        })
    }

    /// Every row of an unlabelled export is of one step; a pause or lost rows cut it in parts,
    /// each cut into steps where its drive changes, the records numbered in order.
    fn split_unlabelled(&mut self, path: &Path, times: &[f64]) -> Result<(), CsvError> {
        let driven = self.layout.profile.driven_channel();
        let steps = std::mem::take(&mut self.unlabelled);
        let parts: Vec<(&Record, &[f64])> = steps
            .iter()
            .map(|s| {
                let (run, first) = (&s.assembled.record, s.assembled.first_sample);
                (run, &times[first..first + run.len()])
            })
            .collect();
        let found = split_parts(&parts, driven, &SegmentOptions::default()).map_err(|e| {
            CsvError::Unlabelled {
                path: path.to_path_buf(),
                first_s: times.first().copied().unwrap_or(0.0),
                last_s: times.last().copied().unwrap_or(0.0),
                message: e.to_string(),
            }
        })?;
        drop(parts);
        drop(steps);
        for (record, frequency) in found {
            let record = with_excitation(record, frequency, None, None, driven);
            self.records.extend((self.keep)(record));
        }
        Ok(())
    }
}

/// `record` with the excitation its labels and its `driven` channel give: a multisine's or a
/// sweep's labels with the drive's level, else a sine of the labelled `frequency` with the
/// drive's amplitude, or random with its RMS.
fn with_excitation(
    mut record: Record,
    frequency: Option<f64>,
    multisine: Option<MultisineLabel>,
    sweep: Option<SweepLabel>,
    driven: Channel,
) -> Record {
    let level = rms_about_mean(record.channel(driven).expect("a required channel"));
    record.excitation = match (multisine, sweep) {
        (Some(m), _) => Excitation::Multisine {
            base_frequency_hz: m.base_frequency_hz,
            lines: m.lines,
            rms: level,
        },
        (None, Some(s)) => Excitation::Sweep {
            law: SweepLaw {
                kind: s.kind,
                amplitude: sine_amplitude_from_rms(level),
                start_frequency_hz: s.start_frequency_hz,
                end_frequency_hz: s.end_frequency_hz,
                duration_s: record.len() as f64 / record.sample_rate_hz,
            },
        },
        (None, None) => estimated_excitation(frequency, level),
    };
    record
}
