//! Runs of the benches labs run beyond the paper's two, as named [`RunSpec`] constructors:
//! what `forcemap simulate --system damper-dyno|shaker-sdof` writes, the committed sample bag
//! `bags/damper_dyno_40db` holds, and the element-test checks simulate.

use super::element::ElementDrive;
use super::excitation::StepSpec;
use super::excitation::{
    PAPER_RIG_FREQUENCIES_HZ, PAPER_RIG_SAMPLES_PER_RECORD, PAPER_RIG_SINE_AMPLITUDE_M,
    paper_rig_random_steps,
};
use super::periodic_multisine::{MultisineDesign, MultisinePlan};
use super::run::RunSpec;
use super::truth::{AsymmetricDamping, TruthElement};
use crate::element::Friction;
use crate::phasor::SweepKind;
use crate::signal::bouc_wen::HysteresisLaw;

/// Components of the band-random identification record of [`RunSpec::rig_random`].
pub const RIG_RANDOM_COMPONENTS: usize = 256;

/// A stepped-sine program over a grid: every frequency at the first amplitude, then at the
/// next (amplitude in the driven channel's unit).
pub fn sine_grid(frequencies_hz: &[f64], amplitudes: &[f64]) -> Vec<StepSpec> {
    amplitudes
        .iter()
        .flat_map(|&amplitude| {
            frequencies_hz
                .iter()
                .map(move |&frequency_hz| StepSpec::Sine {
                    frequency_hz,
                    amplitude,
                })
        })
        .collect()
}

impl RunSpec {
    /// A twin-tube damper on a displacement-driven dyno: 150 N gas preload, 2000 N/m gas
    /// spring, rebound 2500 and compression 1000 N s/m, 40 N of seal friction, 0.8 kg between
    /// load cell and damper; 1, 2, 4 and 8 Hz at 5, 10 and 20 mm, 4 s per step at 1 kHz.
    /// Its `damper` model (offset + k x + c x' + ca |x'| + fd sgn x') has the truth
    /// [`RunSpec::DAMPER_DYNO_THETA`].
    pub fn damper_dyno(snr_db: Option<f64>, seed: u64) -> RunSpec {
        let element = TruthElement {
            preload_n: 150.0,
            friction: Some(Friction::coulomb(40.0)),
            asymmetric_damping: Some(AsymmetricDamping {
                rebound_n_s_per_m: 2500.0,
                compression_n_s_per_m: 1000.0,
            }),
            ..TruthElement::linear(2000.0, 0.0)
        };
        RunSpec {
            snr_db,
            seed,
            ..RunSpec::element_test(
                ElementDrive::Displacement,
                0.8,
                element,
                sine_grid(&[1.0, 2.0, 4.0, 8.0], &[0.005, 0.01, 0.02]),
                1000.0,
                4000,
            )
        }
    }

    /// [`RunSpec::damper_dyno`] driven by one linear or logarithmic 1-8 Hz displacement sweep of
    /// 10 mm (peak speed 0.5 m/s at 8 Hz) as long as the twelve steps of the stepped program.
    pub fn damper_dyno_sweep(kind: SweepKind, snr_db: Option<f64>, seed: u64) -> RunSpec {
        RunSpec::damper_dyno(snr_db, seed).swept(kind, [1.0, 8.0], 0.01)
    }

    /// This run with its steps replaced by one sweep over `band_hz` at `amplitude` (in the
    /// driven quantity's unit), as long as the steps were together.
    fn swept(self, kind: SweepKind, band_hz: [f64; 2], amplitude: f64) -> RunSpec {
        RunSpec {
            steps: vec![StepSpec::Sweep {
                sweep: kind,
                start_frequency_hz: band_hz[0],
                end_frequency_hz: band_hz[1],
                amplitude,
            }],
            samples_per_record: self.samples_per_record * self.steps.len(),
            ..self
        }
    }

    /// The `damper` model's parameters of [`RunSpec::damper_dyno`]: c and ca are the mean
    /// and half the difference of rebound and compression damping.
    pub const DAMPER_DYNO_THETA: [(&'static str, f64); 5] = [
        ("offset", 150.0),
        ("k", 2000.0),
        ("c", 1750.0),
        ("ca", 750.0),
        ("fd", 40.0),
    ];

    /// A force-driven single-DOF system on a shaker: 2 kg on a spring of 20 000 N/m with
    /// cubic stiffness 5e7 N/m^3 and 60 N s/m, resonant near 16 Hz; 8 to 25 Hz at 20 and 40 N,
    /// 2 s per step at 2 kHz. Its mass is meant to be identified (parameter `m`).
    pub fn shaker_sdof(snr_db: Option<f64>, seed: u64) -> RunSpec {
        let element = TruthElement {
            cubic_stiffness_n_per_m3: 5.0e7,
            ..TruthElement::linear(2.0e4, 60.0)
        };
        RunSpec {
            snr_db,
            seed,
            ..RunSpec::element_test(
                ElementDrive::Force,
                2.0,
                element,
                sine_grid(&[8.0, 12.0, 15.0, 17.0, 20.0, 25.0], &[20.0, 40.0]),
                2000.0,
                4000,
            )
        }
    }

    /// The shaker's system driven by two periodic multisines and a third, non-periodic record
    /// for validation: random-odd lines of 0.5 Hz over 4-25 Hz (around its 16 Hz resonance),
    /// 60 N RMS, nine periods of 2 s each (the first one the transient), then band-random force
    /// over the same band at the same RMS for as long; 2 kHz. What `forcemap simulate --system
    /// shaker-sdof --excitation multisine` writes (the multisine acceptance case).
    pub fn shaker_sdof_multisine(snr_db: Option<f64>, seed: u64) -> RunSpec {
        let plan = MultisinePlan {
            base_frequency_hz: 0.5,
            band_hz: [4.0, 25.0],
            rms: 60.0,
            design: MultisineDesign::RandomOdd,
            periods: 9,
        };
        let stepped = RunSpec::shaker_sdof(snr_db, seed);
        let mut spec = RunSpec {
            snr_db,
            seed,
            ..RunSpec::force_driven_multisine(2.0, stepped.element, &plan, 2, 2000.0)
        };
        spec.steps.push(StepSpec::Random {
            low_hz: 4.0,
            high_hz: 25.0,
            rms: 60.0,
            components: 64,
        });
        spec
    }

    /// A force-driven Duffing oscillator on a shaker measured with one-period multisines: 2 kg
    /// on 40 000 N/m with cubic stiffness 2e9 N/m^3 and 60 N s/m (22.5 Hz, 10.6 % of
    /// critical), six one-period random-phase multisines of 40 N RMS on every 0.5 Hz line from
    /// 5 to 60 Hz, back to back at 1 kHz (the first from rest, the others where the last one
    /// left the mass), so no record has settled periods: records for output error
    /// ([`crate::identify::RecordsOutputError`]). The `cubic` model's truth is
    /// [`RunSpec::SHAKER_DUFFING_THETA`].
    pub fn shaker_duffing_one_period(snr_db: Option<f64>, seed: u64) -> RunSpec {
        let [(_, k), (_, c), (_, s)] = RunSpec::SHAKER_DUFFING_THETA;
        let element = TruthElement {
            cubic_stiffness_n_per_m3: s,
            ..TruthElement::linear(k, c)
        };
        RunSpec::shaker_one_period_multisines(element, snr_db, seed)
    }

    /// The same shaker's single-DOF system with a hysteresis loop in place of the cubic
    /// stiffness: 2 kg on 40 000 N/m and 60 N s/m with a Bouc-Wen loop of alpha 20 000 N/m
    /// ([`RunSpec::SHAKER_LOOP`]: yield 0.4 mm, saturating at 8 N, n 2, r 0.7), measured with
    /// the same six one-period multisines. The `linear+hysteresis` model's truth.
    pub fn shaker_loop_one_period(snr_db: Option<f64>, seed: u64) -> RunSpec {
        let [(_, k), (_, c)] = RunSpec::SHAKER_LOOP_THETA;
        let (law, alpha) = RunSpec::SHAKER_LOOP;
        let element = TruthElement {
            bouc_wen: Some(law.bouc_wen(alpha)),
            ..TruthElement::linear(k, c)
        };
        RunSpec::shaker_one_period_multisines(element, snr_db, seed)
    }

    /// The `linear` terms of [`RunSpec::shaker_loop_one_period`] (its moving mass is 2 kg).
    pub const SHAKER_LOOP_THETA: [(&'static str, f64); 2] = [("k", 4.0e4), ("c", 60.0)];

    /// The loop of [`RunSpec::shaker_loop_one_period`]: its law and alpha [N/m].
    pub const SHAKER_LOOP: (HysteresisLaw, f64) = (
        HysteresisLaw {
            yield_m: 4.0e-4,
            n: 2.0,
            r: 0.7,
        },
        2.0e4,
    );

    /// `element` on the 2 kg shaker under six one-period multisines (see
    /// [`RunSpec::shaker_duffing_one_period`]).
    fn shaker_one_period_multisines(
        element: TruthElement,
        snr_db: Option<f64>,
        seed: u64,
    ) -> RunSpec {
        let step = StepSpec::Multisine {
            base_frequency_hz: 0.5,
            low_hz: 5.0,
            high_hz: 60.0,
            rms: 40.0,
            design: MultisineDesign::Full,
        };
        RunSpec {
            snr_db,
            seed,
            ..RunSpec::element_test(
                ElementDrive::Force,
                2.0,
                element,
                vec![step; 6],
                1000.0,
                2000,
            )
        }
    }

    /// The `cubic` model's parameters of [`RunSpec::shaker_duffing_one_period`] (its moving mass
    /// is 2 kg).
    pub const SHAKER_DUFFING_THETA: [(&'static str, f64); 3] =
        [("k", 4.0e4), ("c", 60.0), ("s", 2.0e9)];

    /// The paper's rig driven by one sine sweep over the stepped sine's band and time: 1.6 to
    /// 3.4 Hz at 6 mm in 130 s (the ten 13 s steps), `kind` linear or logarithmic; with
    /// `validation`, then the two band-random validation records of the paper run (each as long
    /// as the sweep: a run has one record length).
    pub fn rig_sweep(kind: SweepKind, validation: bool, snr_db: Option<f64>, seed: u64) -> RunSpec {
        let mut steps = vec![StepSpec::Sweep {
            sweep: kind,
            start_frequency_hz: PAPER_RIG_FREQUENCIES_HZ[0],
            end_frequency_hz: PAPER_RIG_FREQUENCIES_HZ[PAPER_RIG_FREQUENCIES_HZ.len() - 1],
            amplitude: PAPER_RIG_SINE_AMPLITUDE_M,
        }];
        if validation {
            steps.extend(paper_rig_random_steps());
        }
        RunSpec {
            snr_db,
            seed,
            samples_per_record: PAPER_RIG_SAMPLES_PER_RECORD * PAPER_RIG_FREQUENCIES_HZ.len(),
            ..RunSpec::rig(steps)
        }
    }

    /// The paper's rig driven by one band-random record as the identification record, over the
    /// stepped sine's band and time: 1.6-3.4 Hz, 130 s, RMS 6 mm / sqrt 2 (the power of the
    /// 6 mm sines), [`RIG_RANDOM_COMPONENTS`] components.
    pub fn rig_random(snr_db: Option<f64>, seed: u64) -> RunSpec {
        let steps = vec![StepSpec::Random {
            low_hz: PAPER_RIG_FREQUENCIES_HZ[0],
            high_hz: PAPER_RIG_FREQUENCIES_HZ[PAPER_RIG_FREQUENCIES_HZ.len() - 1],
            rms: PAPER_RIG_SINE_AMPLITUDE_M / 2f64.sqrt(),
            components: RIG_RANDOM_COMPONENTS,
        }];
        RunSpec {
            snr_db,
            seed,
            samples_per_record: PAPER_RIG_SAMPLES_PER_RECORD * PAPER_RIG_FREQUENCIES_HZ.len(),
            ..RunSpec::rig(steps)
        }
    }

    /// The shaker's system ([`RunSpec::shaker_sdof`]) driven by one force sweep over its
    /// stepped sine's band and time: 8 to 25 Hz at 40 N in 24 s, through its 16 Hz resonance
    /// (settling time about 0.07 s, so the sweep stays settled), `kind` linear or logarithmic.
    pub fn shaker_sdof_sweep(kind: SweepKind, snr_db: Option<f64>, seed: u64) -> RunSpec {
        RunSpec::shaker_sdof(snr_db, seed).swept(kind, [8.0, 25.0], 40.0)
    }
}
