//! Input signals with exact first and second time derivatives.
//!
//! Every input of the simulators is a [`PiecewiseSignal`]: a list of smooth pieces
//! ([`Piece`]), each valid from its start time until the next piece starts. Inside one piece
//! the value and its derivatives are closed-form, so the integrators never differentiate
//! numerically. Piece boundaries are integration breakpoints; a piece is evaluated with a
//! reference time `t_ref` (the midpoint of the current integration interval) that selects the
//! piece, so the integrator sees the left limit at the end of an interval and the right limit
//! at its start.

use std::f64::consts::PI;
use std::sync::Arc;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::periodic_multisine::{MultisineDesign, multisine_lines, periodic_multisine};
pub use super::spline::{CubicSpline, SplineEnds};
use crate::phasor::{SweepKind, SweepLaw};
use crate::record::{Excitation, Record};

/// Paper default sampling rate of the suspension rig [Hz].
pub const PAPER_RIG_SAMPLE_RATE_HZ: f64 = 100.0;
/// Paper default record length of the suspension rig [samples] (13 s at 100 Hz).
pub const PAPER_RIG_SAMPLES_PER_RECORD: usize = 1300;
/// Paper stepped-sine frequencies of the rig: 1.6 to 3.4 Hz in 0.2 Hz steps (10 steps).
pub const PAPER_RIG_FREQUENCIES_HZ: [f64; 10] = [1.6, 1.8, 2.0, 2.2, 2.4, 2.6, 2.8, 3.0, 3.2, 3.4];
/// Paper validation bands of band-limited random base motion [Hz].
pub const PAPER_RIG_RANDOM_BANDS_HZ: [[f64; 2]; 2] = [[1.5, 2.5], [2.5, 3.5]];
/// Default sine base amplitude of the rig [m].
///
/// Not stated in the paper; derived from its r values (Table 2, Coulomb model: k x 58 %,
/// c x' 27.4 %, F_d sgn 14.5 % of the transmitted force, each from the RMS of its term).
/// With k = 6380 N/m and F_d = 12.3 N, r_k / r_F = k x_rms / F_d = 4 gives a relative
/// displacement RMS of about 7.7 mm over the fitting data (and r_c / r_F gives x'_rms /
/// x_rms of about 16 rad/s, i.e. 2.6 Hz, consistent with the 1.6-3.4 Hz steps). The linear
/// relative transmissibility m w^2 / |k - m w^2 + j w c| of the identified rig is 1.1-2.6
/// over the steps, so a 6 mm base amplitude gives a relative RMS of about 8.4 mm without
/// friction, somewhat less with it: 6 mm is the round value that matches.
pub const PAPER_RIG_SINE_AMPLITUDE_M: f64 = 0.006;
/// Default RMS of the band-limited random base motion of the rig [m].
pub const PAPER_RIG_RANDOM_RMS_M: f64 = 0.004;
/// Default number of components of a band-limited random multisine.
pub const DEFAULT_MULTISINE_COMPONENTS: usize = 64;
/// 3-DOF example: drive frequency [Hz] (force on m2).
pub const THREE_DOF_FREQUENCY_HZ: f64 = 5.0;
/// 3-DOF example, CASE I force amplitudes [N].
pub const THREE_DOF_CASE_I_N: [f64; 5] = [5.0, 10.0, 15.0, 20.0, 25.0];
/// 3-DOF example, CASE II force amplitudes [N].
pub const THREE_DOF_CASE_II_N: [f64; 5] = [50.0, 60.0, 70.0, 80.0, 90.0];
/// 3-DOF default sampling rate [Hz]: 200 samples per period at 5 Hz.
pub const THREE_DOF_SAMPLE_RATE_HZ: f64 = 1000.0;
/// 3-DOF default record length [samples]: 8 s per step (40 periods at 5 Hz). The transient
/// after an amplitude change decays at about 1.3 /s (measured: the change of x2 - x3 from one
/// period to the next, relative to its amplitude, is 0.1-3 % after 3 s, 1e-4 or less after
/// 8 s and about 1e-6 after 10 s), so 3 s records are not yet periodic; 8 s are.
pub const THREE_DOF_SAMPLES_PER_RECORD: usize = 8000;

/// Value and first two time derivatives of a signal.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Derivs {
    pub value: f64,
    pub d1: f64,
    pub d2: f64,
}

/// A band-limited random signal: a multisine with random phases and frequencies spread
/// uniformly over the band (one component drawn uniformly in each of `n` equal sub-bands),
/// equal amplitudes. Time is local: `t = 0` is the start of the record.
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    pub band_hz: [f64; 2],
    /// Amplitude of every component.
    pub component_amplitude: f64,
    /// Angular frequencies [rad/s].
    pub omegas: Vec<f64>,
    /// Phases [rad].
    pub phases: Vec<f64>,
}

impl Multisine {
    /// A seeded multisine on `[low_hz, high_hz]` with `components` components, scaled so that
    /// the RMS of its samples over one record (`samples` at `sample_rate_hz`) is exactly
    /// `rms`. (The components are not orthogonal over a finite record, so scaling by the
    /// nominal `a sqrt(n/2)` would miss the target by several %.)
    pub fn band_limited(
        low_hz: f64,
        high_hz: f64,
        rms: f64,
        components: usize,
        seed: u64,
        samples: usize,
        sample_rate_hz: f64,
    ) -> Multisine {
        let n = components.max(1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let df = (high_hz - low_hz) / n as f64;
        let mut omegas = Vec::with_capacity(n);
        let mut phases = Vec::with_capacity(n);
        for j in 0..n {
            let u: f64 = rng.random();
            let p: f64 = rng.random();
            omegas.push(2.0 * PI * (low_hz + (j as f64 + u) * df));
            phases.push(2.0 * PI * p);
        }
        let mut ms = Multisine {
            band_hz: [low_hz, high_hz],
            component_amplitude: 1.0,
            omegas,
            phases,
        };
        let m = samples.max(1);
        let ss: f64 = (0..m)
            .map(|i| ms.eval(i as f64 / sample_rate_hz).value.powi(2))
            .sum();
        let measured = (ss / m as f64).sqrt();
        ms.component_amplitude = if measured > 0.0 { rms / measured } else { 0.0 };
        ms
    }

    /// Value and exact derivatives at local time `t` [s].
    pub fn eval(&self, t: f64) -> Derivs {
        let a = self.component_amplitude;
        let mut d = Derivs::default();
        for (&w, &p) in self.omegas.iter().zip(&self.phases) {
            let (s, c) = (w * t + p).sin_cos();
            d.value += a * s;
            d.d1 += a * w * c;
            d.d2 -= a * w * w * s;
        }
        d
    }
}

/// One smooth piece of a piecewise signal.
#[derive(Debug, Clone, PartialEq)]
pub enum Piece {
    /// Constant value (rest).
    Const(f64),
    /// `amplitude * sin(phase + omega (t - t0))`.
    Sine {
        t0: f64,
        amplitude: f64,
        omega: f64,
        phase: f64,
    },
    /// A multisine with local time `t - t0`.
    Multisine { t0: f64, signal: Arc<Multisine> },
    /// An interpolating cubic spline (its interval is chosen by `t_ref`).
    Spline(Arc<CubicSpline>),
    /// A sine sweep `law.amplitude sin(phi(t - t0))` (phase 0 at `t0`).
    Sweep { t0: f64, law: SweepLaw },
}

impl Piece {
    pub fn eval(&self, t: f64, t_ref: f64) -> Derivs {
        match self {
            Piece::Const(v) => Derivs {
                value: *v,
                d1: 0.0,
                d2: 0.0,
            },
            Piece::Sine {
                t0,
                amplitude,
                omega,
                phase,
            } => {
                let (s, c) = (phase + omega * (t - t0)).sin_cos();
                Derivs {
                    value: amplitude * s,
                    d1: amplitude * omega * c,
                    d2: -amplitude * omega * omega * s,
                }
            }
            Piece::Multisine { t0, signal } => signal.eval(t - t0),
            Piece::Spline(s) => s.eval(t, t_ref),
            Piece::Sweep { t0, law } => sweep_derivs(law, t - t0),
        }
    }
}

/// `A sin(phi)` of a sweep and its exact derivatives at local time `t`: `A w cos(phi)` and
/// `A (w' cos(phi) - w^2 sin(phi))`, `w = 2 pi f(t)`.
pub fn sweep_derivs(law: &SweepLaw, t: f64) -> Derivs {
    let (s, c) = law.phase_rad(t).sin_cos();
    let w = 2.0 * PI * law.frequency_hz(t);
    let dw = 2.0 * PI * law.frequency_rate_hz_per_s(t);
    let a = law.amplitude;
    Derivs {
        value: a * s,
        d1: a * w * c,
        d2: a * (dw * c - w * w * s),
    }
}

/// A piecewise-smooth signal: `pieces[j]` holds from `starts[j]` until `starts[j + 1]`. The
/// first piece starts at minus infinity (the rest value before the run). `shift` delays the
/// whole signal: the value at `t` is the undelayed value at `t - shift`.
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseSignal {
    pub starts: Vec<f64>,
    pub pieces: Vec<Piece>,
    pub shift: f64,
}

impl PiecewiseSignal {
    /// A signal at rest at `rest_value` before its first piece.
    pub fn new(rest_value: f64) -> PiecewiseSignal {
        PiecewiseSignal {
            starts: vec![f64::NEG_INFINITY],
            pieces: vec![Piece::Const(rest_value)],
            shift: 0.0,
        }
    }

    /// Appends a piece starting at `start` (undelayed time; must not decrease).
    pub fn push(&mut self, start: f64, piece: Piece) {
        self.starts.push(start);
        self.pieces.push(piece);
    }

    /// The same signal delayed by `delay_s`.
    pub fn delayed(&self, delay_s: f64) -> PiecewiseSignal {
        PiecewiseSignal {
            shift: self.shift + delay_s,
            ..self.clone()
        }
    }

    /// Index of the piece that holds at `t_ref`.
    pub(crate) fn index(&self, t_ref: f64) -> usize {
        let tr = t_ref - self.shift;
        // Last j with starts[j] <= tr (starts[0] = -inf).
        self.starts.partition_point(|&s| s <= tr).saturating_sub(1)
    }

    /// Value and derivatives at `t` from the piece that holds at `t_ref`.
    pub fn eval(&self, t: f64, t_ref: f64) -> Derivs {
        let j = self.index(t_ref);
        self.pieces[j].eval(t - self.shift, t_ref - self.shift)
    }

    /// Right limit at `t` (the piece starting at or before `t`).
    pub fn eval_right(&self, t: f64) -> Derivs {
        self.eval(t, t)
    }

    /// Left limit at `t` (the piece that holds just before `t`).
    pub fn eval_left(&self, t: f64) -> Derivs {
        let tr = t - self.shift;
        let j = self.starts.partition_point(|&s| s < tr).saturating_sub(1);
        self.pieces[j].eval(tr, tr)
    }

    /// Times where pieces change (delayed), excluding minus infinity.
    pub fn breakpoints(&self) -> Vec<f64> {
        self.starts.iter().skip(1).map(|s| s + self.shift).collect()
    }
}

/// One step (or record) of an excitation program.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StepSpec {
    /// Stepped-sine step; `amplitude` in the unit of the driven quantity.
    Sine { frequency_hz: f64, amplitude: f64 },
    /// Band-limited random record (multisine), scaled to `rms` over the record.
    Random {
        low_hz: f64,
        high_hz: f64,
        rms: f64,
        #[serde(default = "default_components")]
        components: usize,
    },
    /// A periodic multisine (see [`super::periodic_multisine`]): the lines of `design` in
    /// `[low_hz, high_hz]` at multiples of `base_frequency_hz`, `rms` over whole periods, phases
    /// from the run seed and the record index. The record repeats the period from its first
    /// sample on; `samples_per_record` should hold whole periods (the first ones are the
    /// transient).
    Multisine {
        base_frequency_hz: f64,
        low_hz: f64,
        high_hz: f64,
        rms: f64,
        #[serde(default)]
        design: MultisineDesign,
    },
    /// A sine sweep over the whole record (`samples_per_record` at the sample rate), from
    /// `start_frequency_hz` at its first sample to `end_frequency_hz` at its end, starting at
    /// phase 0; `amplitude` in the unit of the driven quantity.
    Sweep {
        sweep: SweepKind,
        start_frequency_hz: f64,
        end_frequency_hz: f64,
        amplitude: f64,
    },
}

fn default_components() -> usize {
    DEFAULT_MULTISINE_COMPONENTS
}

/// One record of a program: how many samples and what drove it.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordPlan {
    pub samples: usize,
    pub excitation: Excitation,
}

/// A sampled excitation program: the input signal of a whole run and its records. Record `k`
/// holds the samples `first_sample(k) .. first_sample(k) + records[k].samples` at times
/// `i / sample_rate_hz`; the run starts at `t = 0` at rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    pub sample_rate_hz: f64,
    pub records: Vec<RecordPlan>,
    pub signal: PiecewiseSignal,
}

impl Program {
    /// A program that drives `signal` over the records' sample counts and excitations, at the
    /// first record's rate: how output error simulates the records it fits.
    pub fn replaying(records: &[&Record], signal: PiecewiseSignal) -> Program {
        Program {
            sample_rate_hz: records[0].sample_rate_hz,
            records: records
                .iter()
                .map(|r| RecordPlan {
                    samples: r.len(),
                    excitation: r.excitation.clone(),
                })
                .collect(),
            signal,
        }
    }

    /// A stepped-sine or random program from steps, each `samples_per_record` long. Sine
    /// steps are phase-continuous (phase accumulator; the first starts at phase 0), so a run
    /// of constant-amplitude sines has a continuous value; random records use seeds derived
    /// from `seed` and the record index.
    pub fn from_steps(
        steps: &[StepSpec],
        sample_rate_hz: f64,
        samples_per_record: usize,
        seed: u64,
    ) -> Program {
        let mut signal = PiecewiseSignal::new(0.0);
        let mut records = Vec::with_capacity(steps.len());
        let mut phase = 0.0_f64;
        let duration = samples_per_record as f64 / sample_rate_hz;
        for (k, step) in steps.iter().enumerate() {
            let t0 = (k * samples_per_record) as f64 / sample_rate_hz;
            // Each step is one piece of the drive and one record plan.
            let (piece, excitation) = match *step {
                StepSpec::Sine {
                    frequency_hz,
                    amplitude,
                } => {
                    let omega = 2.0 * PI * frequency_hz;
                    let piece = Piece::Sine {
                        t0,
                        amplitude,
                        omega,
                        phase,
                    };
                    phase = (phase + omega * duration).rem_euclid(2.0 * PI);
                    (
                        piece,
                        Excitation::Sine {
                            frequency_hz,
                            amplitude,
                        },
                    )
                }
                StepSpec::Random {
                    low_hz,
                    high_hz,
                    rms,
                    components,
                } => {
                    let ms = Multisine::band_limited(
                        low_hz,
                        high_hz,
                        rms,
                        components,
                        derive_seed(seed, 1000 + k as u64),
                        samples_per_record,
                        sample_rate_hz,
                    );
                    (
                        Piece::Multisine {
                            t0,
                            signal: Arc::new(ms),
                        },
                        Excitation::Random {
                            band_hz: Some([low_hz, high_hz]),
                            rms,
                        },
                    )
                }
                StepSpec::Sweep {
                    sweep,
                    start_frequency_hz,
                    end_frequency_hz,
                    amplitude,
                } => {
                    let law = SweepLaw {
                        kind: sweep,
                        amplitude,
                        start_frequency_hz,
                        end_frequency_hz,
                        duration_s: duration,
                    };
                    // A sine step after the sweep goes on from the sweep's end phase.
                    phase = law.phase_rad(duration).rem_euclid(2.0 * PI);
                    (Piece::Sweep { t0, law }, Excitation::Sweep { law })
                }
                StepSpec::Multisine {
                    base_frequency_hz,
                    low_hz,
                    high_hz,
                    rms,
                    design,
                } => {
                    let s = derive_seed(seed, 2000 + k as u64);
                    let lines = multisine_lines(base_frequency_hz, low_hz, high_hz, design, s);
                    let ms = periodic_multisine(base_frequency_hz, &lines, rms, s, sample_rate_hz);
                    (
                        Piece::Multisine {
                            t0,
                            signal: Arc::new(ms),
                        },
                        Excitation::Multisine {
                            base_frequency_hz,
                            lines,
                            rms,
                        },
                    )
                }
            };
            signal.push(t0, piece);
            records.push(RecordPlan {
                samples: samples_per_record,
                excitation,
            });
        }
        // Before the run the signal rests at its value at t = 0 (continuous start).
        if signal.pieces.len() > 1 {
            let v0 = signal.pieces[1].eval(0.0, 0.0).value;
            signal.pieces[0] = Piece::Const(v0);
        }
        Program {
            sample_rate_hz,
            records,
            signal,
        }
    }

    /// Sample index of the first sample of record `k`.
    pub fn first_sample(&self, k: usize) -> usize {
        self.records[..k].iter().map(|r| r.samples).sum()
    }

    /// Total number of samples.
    pub fn total_samples(&self) -> usize {
        self.records.iter().map(|r| r.samples).sum()
    }
}

/// Paper stepped sine of the rig: 1.6 to 3.4 Hz in 0.2 Hz steps at `amplitude_m`.
pub fn paper_rig_sine_steps(amplitude_m: f64) -> Vec<StepSpec> {
    sine_steps(&PAPER_RIG_FREQUENCIES_HZ, amplitude_m)
}

/// A stepped sine: one step per frequency of `frequencies_hz`, each at `amplitude`.
pub fn sine_steps(frequencies_hz: &[f64], amplitude: f64) -> Vec<StepSpec> {
    frequencies_hz
        .iter()
        .map(|&f| StepSpec::Sine {
            frequency_hz: f,
            amplitude,
        })
        .collect()
}

/// The paper's two random validation records of the rig (1.5-2.5 and 2.5-3.5 Hz, 4 mm RMS).
pub fn paper_rig_random_steps() -> Vec<StepSpec> {
    PAPER_RIG_RANDOM_BANDS_HZ
        .iter()
        .map(|&band| paper_rig_random_step(band, PAPER_RIG_RANDOM_RMS_M))
        .collect()
}

/// Paper random validation record of the rig on `band_hz` at `rms_m`.
pub fn paper_rig_random_step(band_hz: [f64; 2], rms_m: f64) -> StepSpec {
    StepSpec::Random {
        low_hz: band_hz[0],
        high_hz: band_hz[1],
        rms: rms_m,
        components: DEFAULT_MULTISINE_COMPONENTS,
    }
}

/// 3-DOF amplitude steps at 5 Hz.
pub fn three_dof_steps(amplitudes_n: &[f64]) -> Vec<StepSpec> {
    amplitudes_n
        .iter()
        .map(|&a| StepSpec::Sine {
            frequency_hz: THREE_DOF_FREQUENCY_HZ,
            amplitude: a,
        })
        .collect()
}

/// SplitMix64 mix of a run seed and a stream number (independent sub-seeds).
pub fn derive_seed(seed: u64, stream: u64) -> u64 {
    let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn multisine_derivatives_match_finite_differences() {
        let ms = Multisine::band_limited(1.5, 2.5, 0.004, 64, 7, 1300, 100.0);
        let h = 1e-4;
        for &t in &[0.3, 2.7, 11.1] {
            let (a, b, c) = (ms.eval(t - h), ms.eval(t), ms.eval(t + h));
            assert!(((c.value - a.value) / (2.0 * h) - b.d1).abs() < 1e-6 * b.d1.abs().max(1e-3));
            assert!(((c.d1 - a.d1) / (2.0 * h) - b.d2).abs() < 1e-6 * b.d2.abs().max(1e-2));
        }
        let rms = ((0..1300)
            .map(|i| ms.eval(i as f64 / 100.0).value.powi(2))
            .sum::<f64>()
            / 1300.0)
            .sqrt();
        assert!((rms - 0.004).abs() < 1e-12);
    }

    #[test]
    fn stepped_sine_is_phase_continuous() {
        let p = Program::from_steps(&paper_rig_sine_steps(0.006), 100.0, 1300, 0);
        for t in p.signal.breakpoints() {
            let (l, r) = (p.signal.eval_left(t), p.signal.eval_right(t));
            assert!(
                (l.value - r.value).abs() < 1e-12,
                "{t}: {} vs {}",
                l.value,
                r.value
            );
        }
        assert_eq!(p.total_samples(), 13000);
    }
}
