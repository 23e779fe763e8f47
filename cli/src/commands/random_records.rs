//! The band-random records of a file `identify` streams. Once a sine step has been read, the
//! random records that follow are not identified from (every sine step read is analysed, or the
//! identification fails, and the sine steps' analyses are what is identified from): they wait
//! on disk ([`SpilledRecords`]) until the model found is validated on them, so that memory does
//! not grow with them.

use anyhow::Context;
use forcemap_io::spill::SpilledRecords;
use forcemap_math::model::IdentifiedModel;
use forcemap_math::pipeline::{self, Validation};
use forcemap_math::record::{Excitation, Record};

/// Samples (of one channel) of the spilled records read back and validated at a time: a few
/// hundred records of a rig run, enough for every core, a few MB.
const VALIDATION_PART_SAMPLES: usize = 1 << 18;

/// Whether a streamed file's record waits on disk: a band-random record after a sine step.
pub(super) fn spills(record: &Record, sine_read: bool) -> bool {
    sine_read && matches!(record.excitation, Excitation::Random { .. })
}

/// The rig model simulated on every band-random record in file order
/// ([`pipeline::validate_rig_on_random_records`]): those in `records`, then the spilled ones
/// read back a part at a time, kept without their traces (a streamed identification draws no
/// plots).
pub(super) fn validate_rig(
    fitted: &IdentifiedModel,
    mass_kg: f64,
    records: &[Record],
    spilled: Option<SpilledRecords>,
    file: &str,
) -> anyhow::Result<Vec<Validation>> {
    let context = || format!("{file}: validating on the random records");
    let mut validations =
        pipeline::validate_rig_on_random_records(fitted, mass_kg, records).with_context(context)?;
    if let Some(spilled) = spilled {
        for part in spilled.into_parts(VALIDATION_PART_SAMPLES)? {
            let part = pipeline::validate_rig_on_random_records(fitted, mass_kg, &part?)
                .with_context(context)?;
            validations.extend(part.into_iter().map(Validation::without_traces));
        }
    }
    Ok(validations)
}
