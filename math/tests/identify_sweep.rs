//! A sine sweep on a displacement-driven damper dyno, identified by the short-time harmonic
//! analysis (`phasor::sweep`): each window of whole periods of the sweep's phase gives the
//! equations of a step at the window's frequency. The data are written here in closed form
//! from the dyno damper's truth (`RunSpec::damper_dyno`'s element: gas preload and spring,
//! asymmetric damping, seal friction, 0.8 kg moving mass), not by the analysis's own model.

use forcemap_math::element::Element;
use forcemap_math::identify::{FdMultiOptions, Method, solve_blocks, step_equations};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{SweepKind, SweepLaw, SweepOptions, analyse_sweep};
use forcemap_math::recipe::{SetupConstants, SetupKind};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::sim::RunSpec;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const MOVING_MASS_KG: f64 = 0.8;
const FS_HZ: f64 = 2000.0;

/// The sweep record with noise at `snr_db` on displacement and force.
fn sweep_record(law: &SweepLaw, snr_db: Option<f64>, seed: u64) -> Record {
    let element = RunSpec::damper_dyno(None, 0).element;
    let friction = element.friction().expect("seal friction").kinetic_n;
    let n = (law.duration_s * FS_HZ) as usize;
    let (mut x, mut f) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let t = i as f64 / FS_HZ;
        let (phi, w) = (
            law.phase_rad(t),
            2.0 * std::f64::consts::PI * law.frequency_hz(t),
        );
        let dw = match law.kind {
            SweepKind::Linear => {
                2.0 * std::f64::consts::PI * (law.end_frequency_hz - law.start_frequency_hz)
                    / law.duration_s
            }
            SweepKind::Logarithmic => {
                w * (law.end_frequency_hz / law.start_frequency_hz).ln() / law.duration_s
            }
        };
        let a = law.amplitude;
        let (pos, vel) = (a * phi.sin(), a * w * phi.cos());
        let acc = a * (dw * phi.cos() - w * w * phi.sin());
        let force =
            element.smooth_force(pos, vel, &[]) + friction * vel.signum() + MOVING_MASS_KG * acc;
        x.push(pos);
        f.push(force);
    }
    if let Some(snr) = snr_db {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for v in [&mut x, &mut f] {
            let rms = (v.iter().map(|s| s * s).sum::<f64>() / v.len() as f64).sqrt();
            let noise = Normal::new(0.0, rms / 10f64.powf(snr / 20.0)).expect("std");
            for s in v.iter_mut() {
                *s += noise.sample(&mut rng);
            }
        }
    }
    Record {
        step: 0,
        excitation: Excitation::Random {
            band_hz: Some([law.start_frequency_hz, law.end_frequency_hz]),
            rms: law.amplitude / 2f64.sqrt(),
        },
        sample_rate_hz: FS_HZ,
        start_time_s: 0.0,
        channels: vec![(Channel::RelativeDisplacementM, x), (Channel::ForceN, f)],
    }
}

/// Theta of the `damper` model from the sweep's windows (fd-multi, moving mass known).
fn identify_sweep(law: &SweepLaw, snr_db: Option<f64>, seed: u64) -> Vec<(String, f64)> {
    let record = sweep_record(law, snr_db, seed);
    let windows = analyse_sweep(
        &record,
        law,
        &SweepOptions {
            periods_per_window: 4,
            max_harmonic: 40,
        },
    )
    .expect("analyses");
    assert!(windows.len() >= 20, "{} windows", windows.len());
    let setup = SetupKind::Element
        .resolve(&SetupConstants {
            mass_kg: Some(MOVING_MASS_KG),
            ..SetupConstants::default()
        })
        .expect("resolves")
        .setup()
        .expect("checked");
    let model = Model::by_name("damper", &ModelOptions::default()).expect("model");
    let options = FdMultiOptions::default();
    let blocks: Vec<_> = windows
        .iter()
        .map(|w| step_equations(&model, &setup, Method::FdMulti, w, &options).expect("equations"))
        .collect();
    let id = solve_blocks(&model, &setup, Method::FdMulti, &blocks).expect("solves");
    id.parameters
        .iter()
        .map(|p| (p.name.clone(), p.value))
        .collect()
}

fn worst_error_percent(found: &[(String, f64)]) -> f64 {
    let mut worst: f64 = 0.0;
    for ((name, value), (tn, tv)) in found.iter().zip(RunSpec::DAMPER_DYNO_THETA) {
        assert_eq!(name, tn);
        let err = 100.0 * (value - tv) / tv;
        eprintln!("{name} = {value:.4} (truth {tv}, {err:+.3} %)");
        worst = worst.max(err.abs());
    }
    worst
}

fn law(kind: SweepKind) -> SweepLaw {
    SweepLaw {
        kind,
        amplitude: 0.01,
        start_frequency_hz: 0.5,
        end_frequency_hz: 8.0,
        duration_s: 60.0,
    }
}

/// Noise-free, what is left is the windows' second-order sweep-rate error: 0.007 % (linear)
/// and 0.2 % (logarithmic, whose rate grows with the frequency) at 0.5-8 Hz in 60 s.
#[test]
fn a_noise_free_sweep_gives_the_damper_within_its_sweep_rate_error() {
    for (kind, bound) in [(SweepKind::Linear, 0.02), (SweepKind::Logarithmic, 0.3)] {
        let worst = worst_error_percent(&identify_sweep(&law(kind), None, 0));
        eprintln!("{kind:?} noise-free: worst {worst:.3} %");
        assert!(worst < bound, "{kind:?}: {worst} %");
    }
}

#[test]
fn a_sweep_at_30_db_gives_every_parameter_within_2_percent() {
    for kind in [SweepKind::Linear, SweepKind::Logarithmic] {
        for seed in 1..=3 {
            let worst = worst_error_percent(&identify_sweep(&law(kind), Some(30.0), seed));
            eprintln!("{kind:?} 30 dB seed {seed}: worst {worst:.3} %");
            assert!(worst < 2.0, "{kind:?} seed {seed}: {worst} %");
        }
    }
}
