//! The rig's samples written straight into its records as they are simulated: each record's
//! channel columns and trace are allocated once at their final size and filled in place, where
//! a run-long sample array cut into records afterwards (`split_records`) touched and copied
//! every sample twice more (at 10 kHz, a fifth of a run went to the page faults of those
//! buffers).

use super::excitation::Program;
use super::hybrid::{RunStats, SolverOptions};
use super::rig::{RIG_CHANNELS, RigSetup, run_rig_streamed};
use super::{RecordTrace, SampleTrace, SimError, SimOutput};
use crate::record::{Channel, Record};

/// The rig under `setup` (built from `program`), cut into `program`'s records as
/// `split_records` cuts them, with their traces.
pub(crate) fn simulate_rig_records(
    setup: RigSetup<'_>,
    program: &Program,
    solver: &SolverOptions,
) -> Result<SimOutput, SimError> {
    let n = program.records.len();
    let mut records: Vec<Record> = Vec::with_capacity(n);
    let mut samples: Vec<Vec<SampleTrace>> = Vec::with_capacity(n);
    let mut stick_time_s: Vec<Vec<f64>> = Vec::with_capacity(n);
    let mut first = 0;
    for (k, plan) in program.records.iter().enumerate() {
        records.push(Record {
            step: k,
            excitation: plan.excitation.clone(),
            sample_rate_hz: program.sample_rate_hz,
            start_time_s: first as f64 / program.sample_rate_hz,
            channels: RIG_CHANNELS
                .iter()
                .map(|&c| (c, Vec::with_capacity(plan.samples)))
                .collect(),
        });
        samples.push(Vec::with_capacity(plan.samples));
        stick_time_s.push(vec![0.0; plan.samples]);
        first += plan.samples;
    }
    let mut events = vec![0usize; n];
    // Samples and sample intervals come in order (interval `i` follows sample `i`): a cursor
    // each, (record, its first sample), moved on as they pass the record's end.
    let locate = |cursor: &mut (usize, usize), i: usize| {
        while cursor.0 + 1 < n && i >= cursor.1 + program.records[cursor.0].samples {
            cursor.1 += program.records[cursor.0].samples;
            cursor.0 += 1;
        }
    };
    let (mut at_sample, mut at_interval) = ((0, 0), (0, 0));
    run_rig_streamed(
        setup,
        solver,
        |i, values, trace| {
            locate(&mut at_sample, i);
            let k = at_sample.0;
            // The five columns by index (`RIG_CHANNELS` order), not through an iterator pair.
            let columns = &mut records[k].channels[..5];
            for (j, v) in values.into_iter().enumerate() {
                columns[j].1.push(v);
            }
            samples[k].push(trace);
            true
        },
        |i, stuck_s, ev| {
            // Nothing to add for an interval free of stick and events (the sums start at +0).
            if stuck_s == 0.0 && ev == 0 {
                return;
            }
            locate(&mut at_interval, i);
            let (k, first) = at_interval;
            if let Some(s) = stick_time_s[k].get_mut(i - first) {
                *s += stuck_s;
                events[k] += ev;
            }
        },
    )?;
    let traces = samples
        .into_iter()
        .zip(stick_time_s)
        .zip(events)
        .map(|((samples, stick_time_s), events)| RecordTrace {
            samples,
            stick_time_s,
            events,
        })
        .collect();
    Ok(SimOutput { records, traces })
}

/// Cuts run-long samples into the program's records.
pub(crate) fn split_records<const N: usize>(
    program: &Program,
    channels: &[Channel; N],
    out: &[[f64; N]],
    trace: Vec<SampleTrace>,
    stats: &RunStats,
) -> SimOutput {
    let mut records = Vec::with_capacity(program.records.len());
    let mut traces = Vec::with_capacity(program.records.len());
    let mut first = 0;
    for (k, plan) in program.records.iter().enumerate() {
        let range = first..first + plan.samples;
        records.push(Record {
            step: k,
            excitation: plan.excitation.clone(),
            sample_rate_hz: program.sample_rate_hz,
            start_time_s: first as f64 / program.sample_rate_hz,
            channels: channels
                .iter()
                .enumerate()
                .map(|(j, &c)| (c, out[range.clone()].iter().map(|s| s[j]).collect()))
                .collect(),
        });
        traces.push(RecordTrace {
            samples: trace[range.clone()].to_vec(),
            stick_time_s: stats.stick_time_s[range.clone()].to_vec(),
            events: stats.events[range.clone()].iter().sum(),
        });
        first += plan.samples;
    }
    SimOutput { records, traces }
}
