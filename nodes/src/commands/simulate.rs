//! `forcemap simulate`: a test-bench CSV export or a bag from the simulators, with effects
//! planted in the truth model if asked.

use anyhow::bail;
use forcemap_math::sim::excitation::PAPER_RIG_RANDOM_BANDS_HZ;
use forcemap_math::sim::{self, RigEffects, RigRun, SimSpec, ThreeDofRun, TruthElement};

use crate::cli::{CaseArg, EffectArgs, SimulateArgs, SystemArg};
use crate::csv_export::{CsvProfile, write_csv};
use crate::rig_bag::{DEFAULT_RUN_START, write_rig_bag};

/// The truth element with the planted element effects.
fn planted_element(mut element: TruthElement, e: &EffectArgs) -> anyhow::Result<TruthElement> {
    let finite = |name: &str, v: Option<f64>| -> anyhow::Result<Option<f64>> {
        match v {
            Some(x) if !x.is_finite() => bail!("--{name} = {x}: not a finite number"),
            other => Ok(other),
        }
    };
    if let Some(s) = finite("cubic-stiffness-n-per-m3", e.cubic_stiffness_n_per_m3)? {
        element.cubic_stiffness_n_per_m3 = s;
    }
    if let Some(k2) = finite(
        "quadratic-stiffness-n-per-m2",
        e.quadratic_stiffness_n_per_m2,
    )? {
        element.quadratic_stiffness_n_per_m2 = k2;
    }
    if let Some(c2) = finite(
        "quadratic-damping-n-s2-per-m2",
        e.quadratic_damping_n_s2_per_m2,
    )? {
        element.quadratic_damping_n_s2_per_m2 = c2;
    }
    if let Some(extra) = finite("stribeck-breakaway-n", e.stribeck_breakaway_n)? {
        let Some(f) = element.friction.as_mut() else {
            bail!(
                "--stribeck-breakaway-n: this element has no Coulomb friction to add a Stribeck peak to"
            );
        };
        if extra < 0.0 || e.stribeck_velocity_mps.is_nan() || e.stribeck_velocity_mps <= 0.0 {
            bail!("--stribeck-breakaway-n must be >= 0 and --stribeck-velocity-mps > 0");
        }
        f.breakaway_n = f.kinetic_n + extra;
        f.stribeck_velocity_mps = e.stribeck_velocity_mps;
    }
    Ok(element)
}

/// The planted rig-level effects.
fn planted_rig_effects(e: &EffectArgs) -> anyhow::Result<RigEffects> {
    let mut fx = RigEffects::default();
    if let Some(d) = e.exciter_delay_s {
        if !(d >= 0.0 && d.is_finite()) {
            bail!("--exciter-delay-s = {d}: must be a delay >= 0 s");
        }
        fx.exciter_delay_s = d;
    }
    if let Some(fc) = e.sensor_lowpass_hz {
        if !(fc > 0.0 && fc.is_finite()) {
            bail!("--sensor-lowpass-hz = {fc}: must be a cutoff > 0 Hz");
        }
        fx.sensor_lowpass_hz = Some(fc);
    }
    if let Some(m) = e.mass_factor {
        if !(m > 0.0 && m.is_finite()) {
            bail!("--mass-factor = {m}: must be > 0");
        }
        fx.mass_factor = m;
    }
    Ok(fx)
}

pub fn run(args: &SimulateArgs) -> anyhow::Result<()> {
    let (spec, profile) = match args.system {
        SystemArg::Rig => {
            let element = planted_element(TruthElement::rig_coulomb(), &args.effects)?;
            let mut run = RigRun {
                snr_db: args.snr_db,
                seed: args.seed,
                effects: planted_rig_effects(&args.effects)?,
                ..RigRun::paper_sine(element)
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
            let e = &args.effects;
            if e.exciter_delay_s.is_some()
                || e.sensor_lowpass_hz.is_some()
                || e.mass_factor.is_some()
            {
                bail!(
                    "--exciter-delay-s, --sensor-lowpass-hz and --mass-factor apply to the rig (--system rig) only"
                );
            }
            let mut run = match args.case {
                CaseArg::I => ThreeDofRun::case_i(),
                CaseArg::Ii => ThreeDofRun::case_ii(),
            };
            run.element = planted_element(run.element, e)?;
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
