//! A simulated run record by record, in memory independent of its length (the sensor node's
//! long runs): [`RunSpec::simulate_streamed`] gives the records of [`RunSpec::simulate`] bit for
//! bit, one at a time, the simulator's state carried from record to record.
//!
//! The rig is integrated sample by sample and cut into records as they fill. Its noise depends
//! on each channel's RMS over the whole run, so a noisy run is simulated twice: once for the
//! RMS, once to publish (the whole-run simulation's noise, [`NoiseStreams`]).

use super::noise::{NoiseStreams, RunRms};
use super::rig::{RIG_CHANNELS, program_setup, run_rig_streamed};
use super::run::{RunSpec, RunSystem};
use super::{Program, SimError, excitation};
use crate::record::Record;

impl RunSpec {
    /// The records of [`RunSpec::simulate`], handed one at a time to `on_record` (false stops
    /// the run). The rig is streamed; the other systems' runs (short) are simulated whole and
    /// then handed out.
    pub fn simulate_streamed(
        &self,
        mut on_record: impl FnMut(Record) -> bool,
    ) -> Result<(), SimError> {
        let RunSystem::Rig {
            nominal_mass_kg,
            effects,
            initial,
        } = &self.system
        else {
            for r in self.simulate()? {
                if !on_record(r) {
                    break;
                }
            }
            return Ok(());
        };
        if self.samples_per_record == 0 || self.steps.is_empty() {
            // The whole-run simulation's error.
            return self.simulate().map(|_| ());
        }
        let program = self.program();
        let rig = |on_record: &mut dyn FnMut(Record) -> bool| {
            let setup = program_setup(&self.element, *nominal_mass_kg, &program, effects, *initial);
            simulate_records(setup, &program, &self.solver, on_record)
        };
        let mut noise = match self.snr_db {
            None => None,
            Some(_) => {
                let mut rms = RunRms::default();
                rig(&mut |r| {
                    rms.add(&r);
                    true
                })?;
                NoiseStreams::new(
                    &rms,
                    self.snr_db,
                    excitation::derive_seed(self.seed, super::run::NOISE_STREAM),
                )
            }
        };
        rig(&mut |mut r| {
            if let Some(n) = &mut noise {
                n.add(&mut r);
            }
            on_record(r)
        })
    }
}

/// The rig's noise-free records under `program`, one at a time.
fn simulate_records(
    setup: super::rig::RigSetup<'_>,
    program: &Program,
    solver: &super::SolverOptions,
    on_record: &mut dyn FnMut(Record) -> bool,
) -> Result<(), SimError> {
    let mut k = 0usize;
    let mut first = 0usize;
    let mut block: Vec<[f64; 5]> = Vec::new();
    run_rig_streamed(
        setup,
        solver,
        |_, channels, _| {
            block.push(channels);
            let plan = &program.records[k];
            if block.len() < plan.samples {
                return true;
            }
            // As `split_records` cuts them.
            let record = Record {
                step: k,
                excitation: plan.excitation.clone(),
                sample_rate_hz: program.sample_rate_hz,
                start_time_s: first as f64 / program.sample_rate_hz,
                channels: RIG_CHANNELS
                    .iter()
                    .enumerate()
                    .map(|(j, &c)| (c, block.iter().map(|s| s[j]).collect()))
                    .collect(),
            };
            block.clear();
            first += plan.samples;
            k += 1;
            on_record(record)
        },
        |_, _, _| {},
    )
}
