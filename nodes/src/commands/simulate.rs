//! `forcemap simulate`: a test-bench CSV export from the simulators.

use forcemap_math::sim::excitation::PAPER_RIG_RANDOM_BANDS_HZ;
use forcemap_math::sim::{self, RigRun, SimSpec, ThreeDofRun, TruthElement};

use crate::cli::{CaseArg, SimulateArgs, SystemArg};
use crate::csv_export::{CsvProfile, write_csv};

pub fn run(args: &SimulateArgs) -> anyhow::Result<()> {
    let (spec, profile) = match args.system {
        SystemArg::Rig => {
            let mut run = RigRun {
                snr_db: args.snr_db,
                seed: args.seed,
                ..RigRun::paper_sine(TruthElement::rig_coulomb())
            };
            if !args.no_random {
                for band in PAPER_RIG_RANDOM_BANDS_HZ {
                    run.steps.push(sim::excitation::paper_rig_random_step(
                        band,
                        sim::excitation::PAPER_RIG_RANDOM_RMS_M,
                    ));
                }
            }
            (SimSpec::Rig(run), CsvProfile::Rig)
        }
        SystemArg::ThreeDof => {
            let run = match args.case {
                CaseArg::I => ThreeDofRun::case_i(),
                CaseArg::Ii => ThreeDofRun::case_ii(),
            };
            (
                SimSpec::ThreeDof(ThreeDofRun {
                    snr_db: args.snr_db,
                    seed: args.seed,
                    ..run
                }),
                CsvProfile::DrivePoint,
            )
        }
    };
    let records = sim::simulate(&spec)?;
    write_csv(&args.csv, &records, profile)?;
    eprintln!(
        "wrote {} ({} records, {} samples, {} profile)",
        args.csv.display(),
        records.len(),
        records.iter().map(|r| r.len()).sum::<usize>(),
        profile
    );
    Ok(())
}
