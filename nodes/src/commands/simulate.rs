//! `forcemap simulate`: a test-bench CSV export from the simulators.

use forcemap_math::sim::excitation::PAPER_RIG_RANDOM_BANDS_HZ;
use forcemap_math::sim::{self, RigRun, SimSpec, ThreeDofRun, TruthElement};

use crate::cli::{CaseArg, SimulateArgs, SystemArg};
use crate::csv_export::{CsvProfile, write_csv};
use crate::rig_bag::{DEFAULT_RUN_START, write_rig_bag};

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
    let what = format!(
        "{} records, {} samples, {} profile",
        records.len(),
        records.iter().map(|r| r.len()).sum::<usize>(),
        profile
    );
    if let Some(csv) = &args.csv {
        write_csv(csv, &records, profile)?;
        eprintln!("wrote {} ({what})", csv.display());
    }
    if let Some(bag) = &args.bag {
        let mass = [("mass_kg", forcemap_math::sim::rig::PAPER_RIG_MASS_KG)];
        let parameters: &[(&str, f64)] = if profile == CsvProfile::Rig {
            &mass
        } else {
            &[]
        };
        let dir = write_rig_bag(
            bag,
            &records,
            profile.driven_channel(),
            parameters,
            DEFAULT_RUN_START,
        )?;
        eprintln!("wrote {} ({what})", dir.display());
    }
    Ok(())
}
