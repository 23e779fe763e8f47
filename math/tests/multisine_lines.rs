//! The excited lines of a periodic multisine found from its driven channel alone, against the
//! designed line set (random-odd, odd, full) at 20 to 40 dB and noise-free, and refused with
//! a clear error where no line stands out (noise only) or the power in the band does not
//! repeat period after period (a band-random record).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_math::phasor::{MultisineError, MultisineOptions, find_multisine_lines};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::sim::{MultisineDesign, MultisinePlan, RunSpec, StepSpec, TruthElement};

const F0_HZ: f64 = 0.5;

fn cubic_sdof() -> TruthElement {
    TruthElement {
        cubic_stiffness_n_per_m3: 5.0e7,
        ..TruthElement::linear(2.0e4, 60.0)
    }
}

/// One multisine record of `design` (0.5 Hz lines over 4-25 Hz, 60 N RMS, 2 kHz, four periods:
/// one transient and three more) driving the cubic single-DOF system.
fn records(design: MultisineDesign, snr_db: Option<f64>, seed: u64) -> Vec<Record> {
    let plan = MultisinePlan {
        base_frequency_hz: F0_HZ,
        band_hz: [4.0, 25.0],
        rms: 60.0,
        design,
        periods: 4,
    };
    RunSpec {
        snr_db,
        seed,
        ..RunSpec::force_driven_multisine(2.0, cubic_sdof(), &plan, 1, 2000.0)
    }
    .simulate()
    .unwrap()
}

fn designed(r: &Record) -> &[usize] {
    match &r.excitation {
        Excitation::Multisine { lines, .. } => lines,
        other => panic!("not a multisine: {other:?}"),
    }
}

#[test]
fn found_lines_are_the_designed_ones_for_every_design_and_noise_level() {
    let designs = [
        MultisineDesign::RandomOdd,
        MultisineDesign::Odd,
        MultisineDesign::Full,
    ];
    for (i, design) in designs.into_iter().enumerate() {
        for (j, snr_db) in [Some(20.0), Some(30.0), Some(40.0), None]
            .into_iter()
            .enumerate()
        {
            let seed = 10 * i as u64 + j as u64 + 1;
            for r in records(design, snr_db, seed) {
                let found =
                    find_multisine_lines(&r, Channel::ForceN, F0_HZ, &MultisineOptions::default())
                        .unwrap_or_else(|e| panic!("{design:?} at {snr_db:?} dB: {e}"));
                assert_eq!(found, designed(&r), "{design:?} at {snr_db:?} dB");
            }
        }
    }
}

/// A band-random record has its power in the band but it does not repeat period after period;
/// a record of noise alone has no line standing out.
#[test]
fn records_without_lines_are_refused_with_a_clear_error() {
    let mut spec = RunSpec {
        snr_db: Some(30.0),
        seed: 3,
        ..RunSpec::force_driven_multisine(
            2.0,
            cubic_sdof(),
            &MultisinePlan {
                base_frequency_hz: F0_HZ,
                band_hz: [4.0, 25.0],
                rms: 60.0,
                design: MultisineDesign::Odd,
                periods: 4,
            },
            1,
            2000.0,
        )
    };
    spec.steps = vec![StepSpec::Random {
        low_hz: 4.0,
        high_hz: 25.0,
        rms: 60.0,
        components: 64,
    }];
    let random = spec.simulate().unwrap().remove(0);
    let e = find_multisine_lines(
        &random,
        Channel::ForceN,
        F0_HZ,
        &MultisineOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            MultisineError::LinesNotPeriodic { step: 0, .. }
                | MultisineError::NoLineStandsOut { step: 0, .. }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("force_n"), "{e}");

    // Noise alone: a deterministic pseudo-random sequence.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let noise: Vec<f64> = (0..16000)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect();
    let mut r = random.clone();
    r.channels = vec![(Channel::ForceN, noise)];
    let e =
        find_multisine_lines(&r, Channel::ForceN, F0_HZ, &MultisineOptions::default()).unwrap_err();
    assert!(
        matches!(e, MultisineError::NoLineStandsOut { step: 0, .. }),
        "{e}"
    );
    let text = e.to_string();
    assert!(
        text.contains("no excited line") && text.contains("0.5 Hz"),
        "{text}"
    );

    let e = find_multisine_lines(
        &r,
        Channel::RelativeDisplacementM,
        F0_HZ,
        &MultisineOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, MultisineError::DrivenMissing { .. }), "{e}");
}
