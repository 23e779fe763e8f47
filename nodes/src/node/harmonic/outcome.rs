//! What the harmonic node makes of a completed step: a sine step's frequency checked against
//! its driven channel (the label is a hint: [`frequency_from_data`], the rule `forcemap
//! identify` applies to the same records), then its analysis from the stream or, when the
//! stream does not match the record (another rate, or a frequency the data corrected), in
//! batch.

use forcemap_io::steps::StepError;
use forcemap_io::steps::unlabelled::{driven_channel_of, frequency_from_data};
use forcemap_math::record::{Excitation, Record};
use forcemap_msgs::builtin_interfaces::Time;

use super::stream::{Analysis, StepStream};
use super::{HarmonicState, Outcome};

impl HarmonicState {
    /// The outcomes of a completed step: the warning of a frequency the data corrected, then
    /// its analysis, record or drop.
    pub(super) fn outcomes(
        &mut self,
        r: Result<Record, StepError>,
        stream: Option<StepStream>,
    ) -> Vec<Outcome> {
        let mut out = Vec::new();
        let r = r.map(|mut rec| {
            if let Some(w) = driven_channel_of(&rec)
                .and_then(|d| frequency_from_data(&mut rec, d, self.frequency_tolerance))
            {
                out.push(Outcome::Warning(w));
            }
            rec
        });
        out.push(self.outcome(r, stream));
        out
    }

    fn outcome(&mut self, r: Result<Record, StepError>, stream: Option<StepStream>) -> Outcome {
        let origin = match &self.finder {
            Some(f) => f.origin(),
            None => self.assembler.origin(),
        }
        .unwrap_or(Time::ZERO);
        match r {
            Ok(rec) => match rec.excitation {
                Excitation::Sine { .. } => {
                    let analysis = match stream.and_then(|s| s.matching(&rec)) {
                        Some(s) => {
                            self.spent = Some(rec);
                            Analysis::Streamed(Box::new(s))
                        }
                        None => Analysis::Batch(rec),
                    };
                    Outcome::Analyse(analysis, origin)
                }
                Excitation::Multisine { .. } => Outcome::Analyse(Analysis::Multisine(rec), origin),
                Excitation::Random { .. } | Excitation::Sweep { .. } => Outcome::Skipped(
                    rec.step,
                    format!(
                        "random record of {} samples: kept for validation, no phasors",
                        rec.len()
                    ),
                ),
            },
            Err(e) => Outcome::Dropped(e),
        }
    }
}
