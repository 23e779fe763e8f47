//! Records that are not steps: sine sweeps (cut into windows by the short-time harmonic
//! analysis, each window then a step at the sweep's frequency there) and band-random records
//! identified in the time domain when a run has nothing else to identify from.

use super::PipelineError;
use crate::identify::{self, IdentifyError, Method, StepEquations, td_range_equations};
use crate::model::Model;
use crate::phasor::{HarmonicAnalysis, SweepOptions, analyse_sweep};
use crate::recipe::Setup;
use crate::record::{Excitation, Record};

/// Leading windows of each sweep record left out of the equations: the first holds the
/// transient of the start (the drive starts at full amplitude from rest). On the paper's rig
/// swept 1.6-3.4 Hz the first window is 2.5 s, about 6 decay times of the rig's free response.
pub const SWEEP_TRANSIENT_WINDOWS: usize = 1;

/// The windows of every sweep record ([`analyse_sweep`] with its default options: 4 periods
/// per window, up to 20 harmonics), each numbered with its record's step so that equations
/// and the time-domain method find their record; the first [`SWEEP_TRANSIENT_WINDOWS`] of each
/// record are dropped.
pub fn analyse_sweep_records(records: &[Record]) -> Result<Vec<HarmonicAnalysis>, PipelineError> {
    let mut out = Vec::new();
    for r in records {
        let Excitation::Sweep { law } = &r.excitation else {
            continue;
        };
        let windows = analyse_sweep(r, law, &SweepOptions::default())?;
        if windows.len() <= SWEEP_TRANSIENT_WINDOWS {
            return Err(PipelineError::Identify(IdentifyError::Step {
                step: r.step,
                problem: format!(
                    "the sweep record holds {} window(s) of {} periods; it needs more than {} (the first is the start transient)",
                    windows.len(),
                    SweepOptions::default().periods_per_window,
                    SWEEP_TRANSIENT_WINDOWS
                ),
            }));
        }
        out.extend(
            windows
                .into_iter()
                .skip(SWEEP_TRANSIENT_WINDOWS)
                .map(|w| HarmonicAnalysis { step: r.step, ..w }),
        );
    }
    Ok(out)
}

/// Identifies `model` on the band-random records of `records` by time-domain FSM, one block
/// per record over all its samples (`td-N`: N evenly spaced samples per record). The only way
/// a random record gives equations: it has no phasors.
pub fn identify_random_records(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
) -> Result<identify::Identification, PipelineError> {
    let random: Vec<&Record> = records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Random { .. }))
        .collect();
    let Some(first) = random.first() else {
        return Err(IdentifyError::NoSteps.into());
    };
    let Method::Td { points_per_step } = method else {
        return Err(IdentifyError::Step {
            step: first.step,
            problem: format!(
                "the data hold only random records, which have no phasors for {method}: identify them in the time domain (--method td-all, or td-N for N samples per record)"
            ),
        }
        .into());
    };
    let blocks = random
        .iter()
        .map(|r| td_range_equations(model, setup, r, 0, r.len(), points_per_step))
        .collect::<Result<Vec<StepEquations>, _>>()?;
    Ok(identify::solve_blocks(model, setup, method, &blocks)?)
}
