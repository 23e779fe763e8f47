//! The library of candidate effects: what each one adds to a baseline model, the values its
//! nonlinear parameter is searched over, and the signature that tells it apart from the others.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::sensor::SensorFilter;
use crate::basis::{
    AbsVelocity, Constant, Cubic, SignVelocity, SignedSquareDisplacement, SignedSquareVelocity,
    SquareDisplacement, StribeckVelocity, Term,
};
use crate::element::GAUSSIAN_STRIBECK_EXPONENT;
use crate::model::Model;
use crate::recipe::SetupKind;
use crate::signal::bouc_wen::{self, HysteresisLaw};

/// A candidate unmodelled effect, by the name the diagnosis reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    CoulombFriction,
    StribeckFriction,
    QuadraticDamping,
    CubicStiffness,
    QuadraticStiffness,
    AsymmetricDamping,
    FreePlay,
    Hysteresis,
    ExciterDelay,
    SensorLowpass,
    MassError,
    Preload,
    SeriesCompliance,
    Drift,
}

impl Effect {
    pub const ALL: [Effect; 14] = [
        Effect::CoulombFriction,
        Effect::StribeckFriction,
        Effect::QuadraticDamping,
        Effect::CubicStiffness,
        Effect::QuadraticStiffness,
        Effect::AsymmetricDamping,
        Effect::FreePlay,
        Effect::Hysteresis,
        Effect::ExciterDelay,
        Effect::SensorLowpass,
        Effect::MassError,
        Effect::Preload,
        Effect::SeriesCompliance,
        Effect::Drift,
    ];

    /// Whether the effect can show in data of a `kind` setup: a constant force (preload) only
    /// moves the base-excited rig's equilibrium, never its motion; an exciter delay and a mass
    /// error are the rig's (its base motion and its mass).
    pub fn applies_to(self, kind: SetupKind) -> bool {
        match self {
            Effect::Preload => kind != SetupKind::BaseExcited,
            Effect::ExciterDelay | Effect::MassError => kind == SetupKind::BaseExcited,
            _ => true,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Effect::CoulombFriction => "coulomb_friction",
            Effect::StribeckFriction => "stribeck_friction",
            Effect::QuadraticDamping => "quadratic_damping",
            Effect::CubicStiffness => "cubic_stiffness",
            Effect::QuadraticStiffness => "quadratic_stiffness",
            Effect::AsymmetricDamping => "asymmetric_damping",
            Effect::FreePlay => "free_play",
            Effect::Hysteresis => "hysteresis",
            Effect::ExciterDelay => "exciter_delay",
            Effect::SensorLowpass => "sensor_lowpass",
            Effect::MassError => "mass_error",
            Effect::Preload => "preload",
            Effect::SeriesCompliance => "series_compliance",
            Effect::Drift => "drift",
        }
    }

    pub fn from_name(name: &str) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.name() == name)
    }

    /// What is added to the baseline, as a formula.
    pub fn added(self) -> &'static str {
        match self {
            Effect::CoulombFriction => "fd sgn(x')",
            Effect::StribeckFriction => {
                "fs sgn(x') exp(-|x'/vs|^delta), vs and the shape exponent delta searched (plus fd sgn(x') if the baseline has no friction)"
            }
            Effect::QuadraticDamping => "c2 x'|x'|",
            Effect::CubicStiffness => "s x^3",
            Effect::QuadraticStiffness => "k2 x|x| + k2a x^2",
            Effect::AsymmetricDamping => "ca |x'|  (rebound c + ca, compression c - ca)",
            Effect::FreePlay => {
                "kfp (x - clamp(x, -neg, pos)): contact at +pos and -neg, the gap searched centred, then each contact point searched and refined (an uneven gap counts one more parameter)"
            }
            Effect::Hysteresis => {
                "alpha z, Bouc-Wen z' = x' - (r |x'| sgn(z) + (1 - r) x') |z|^n / zy^n: yield zy searched with n = 1, r = 1/2, then the shape (n, r) with the yield walked per shape"
            }
            Effect::ExciterDelay => {
                "the element sees the measured base motion delayed by d (fitted from the kinematic identity x_o - x = x_i)"
            }
            Effect::SensorLowpass => {
                "a first- or second-order low-pass (cutoff fc, damping ratio zeta), with or without a delay d, on one channel or on every channel: a family, its member chosen by the channel identities (x_o = x_i + x, -A/(n w)^2 = X_o) or, on every channel, by the element fit"
            }
            Effect::MassError => "the true mass is the nominal one times f, searched",
            Effect::Preload => "f0, a constant force",
            Effect::SeriesCompliance => {
                "the damper c x' in series with a spring ks: per harmonic F (1 + i n w c / ks) = i n w c X; relaxation c / ks searched, c fitted inside"
            }
            Effect::Drift => {
                "the damping drifts over the run: c (1 + r t) x', t the time since the start of the run (each step at its own time), r fitted"
            }
        }
    }

    /// How the effect shows in the data: the signature that tells it apart from the others.
    pub fn signature(self) -> &'static str {
        match self {
            Effect::CoulombFriction => {
                "force jumps at velocity reversals (state plane: near zero velocity); odd harmonics in phase with velocity; relatively largest at low amplitude"
            }
            Effect::StribeckFriction => {
                "extra friction only at low speed: residual near zero velocity, largest at low amplitude and low frequency"
            }
            Effect::QuadraticDamping => {
                "odd harmonics in phase with velocity, growing with speed (high amplitude, high frequency); no jump at reversals"
            }
            Effect::CubicStiffness => {
                "odd harmonics in phase with displacement, growing with amplitude squared; residual at large displacement"
            }
            Effect::QuadraticStiffness => {
                "in phase with displacement; the symmetric part x|x| puts ~20 % of its first harmonic into the 3rd (x^3: 33 %) and grows linearly with amplitude; the asymmetric part x^2 puts DC and the 2nd harmonic in phase with x^2 (not with x'^2 as asymmetric damping does)"
            }
            Effect::AsymmetricDamping => {
                "DC and even harmonics in phase with x'^2: rebound differs from compression; first-harmonic phasors cannot see it"
            }
            Effect::FreePlay => {
                "stiffness missing near x = 0 (state plane: small displacement); odd harmonics in phase with displacement that shrink, relative to the fundamental, at large amplitude"
            }
            Effect::Hysteresis => {
                "a force that lags the displacement after each reversal and saturates over a yield displacement: like friction but rounded, no jump at reversal"
            }
            Effect::ExciterDelay => {
                "the base channel leads the motion the element sees: the relative displacement disagrees with mass minus base displacement by a phase growing with frequency; the element's force law itself is intact"
            }
            Effect::SensorLowpass => {
                "on some channels: the identities that tie the channels together (x_o = x_i + x, a = x_o'') fail by a lag growing with frequency, gone once the filter is undone on those channels; on every channel alike: consistent between channels, so it shows only through the nonlinear terms and in prediction"
            }
            Effect::MassError => {
                "with every element parameter fitted, a mass error scales the fitted force law and the prediction is unchanged (only theta / m is identifiable); it can only show when parameters are held fixed"
            }
            Effect::Preload => {
                "a force that depends on neither displacement nor velocity (a damper's gas force, a mount's static load): the DC of the element force alone; where the force is measured (element test, drive point)"
            }
            Effect::SeriesCompliance => {
                "the damping force lags the velocity by a phase growing with frequency and an in-phase (stiffness) part grows as w^2: the steps' damping falls and their stiffness rises with frequency; oil compressibility, rubber mounts"
            }
            Effect::Drift => {
                "the steps' damping changes with the time they were run at, whatever their frequency and amplitude, and records run later are predicted with the damping of their time: thermal fade"
            }
        }
    }
}

/// What a candidate adds: extra element terms, a hysteresis state, or a transformation of the
/// measured channels.
#[derive(Debug, Clone, Default)]
pub struct Structure {
    pub effects: Vec<Effect>,
    /// Extra basis terms of the element force.
    pub terms: Vec<Arc<dyn Term>>,
    /// Bouc-Wen hysteresis of this member of the family (force alpha z, alpha fitted).
    pub hysteresis: Option<HysteresisLaw>,
    pub transform: Transform,
    /// The searched (nonlinear) parameter, name and value, e.g. ("gap_m", 0.004).
    pub searched: Vec<(String, f64)>,
    /// Parameters this structure adds to the baseline (fitted coefficients and searched values).
    pub extra_parameters: usize,
    /// The baseline's damper `c x'` in series with a spring of relaxation time c / ks [s]
    /// ([`super::series`]).
    pub series_relaxation_s: Option<f64>,
    /// The baseline's damping drifts linearly with the time of the run ([`super::drift`]).
    pub drift: bool,
}

/// A transformation of the measured channels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Transform {
    /// The element sees the base motion this much later than it is measured [s].
    pub delay_s: f64,
    /// Sensor dynamics on some or all of the measured channels.
    pub sensor: Option<SensorFilter>,
    /// True mass / nominal mass.
    pub mass_factor: f64,
}

impl Default for Transform {
    fn default() -> Self {
        Transform {
            delay_s: 0.0,
            sensor: None,
            mass_factor: 1.0,
        }
    }
}

impl Structure {
    /// The union of two structures (a pair of effects).
    pub fn combine(&self, other: &Structure) -> Structure {
        let mut terms = self.terms.clone();
        terms.extend(other.terms.iter().cloned());
        let mut searched = self.searched.clone();
        searched.extend(other.searched.iter().cloned());
        let mut effects = self.effects.clone();
        effects.extend(other.effects.iter().copied());
        Structure {
            effects,
            terms,
            hysteresis: self.hysteresis.or(other.hysteresis),
            transform: Transform {
                delay_s: self.transform.delay_s + other.transform.delay_s,
                sensor: self.transform.sensor.or(other.transform.sensor),
                mass_factor: self.transform.mass_factor * other.transform.mass_factor,
            },
            searched,
            extra_parameters: self.extra_parameters + other.extra_parameters,
            series_relaxation_s: self.series_relaxation_s.or(other.series_relaxation_s),
            drift: self.drift || other.drift,
        }
    }
}

/// Free-play gaps searched centred, relative to the largest relative displacement amplitude
/// (then each contact point, [`super::free_play::CONTACT_FRACTIONS`]).
pub const FREE_PLAY_GAP_FRACTIONS: [f64; 7] = [0.1, 0.2, 0.3, 0.4, 0.6, 0.8, 1.0];
/// Hysteresis yield displacements searched, relative to the largest amplitude.
pub const HYSTERESIS_YIELD_FRACTIONS: [f64; 6] = [0.02, 0.05, 0.1, 0.2, 0.4, 0.8];
/// Stribeck velocities searched, relative to the largest velocity amplitude.
pub const STRIBECK_VELOCITY_FRACTIONS: [f64; 6] = [0.01, 0.02, 0.05, 0.1, 0.2, 0.4];
/// Stribeck shape exponents searched (with every velocity): the Gaussian law (2) and the
/// sharper drops of measured friction curves (1, 0.5), which fall faster just above zero speed
/// and leave a longer tail.
pub const STRIBECK_EXPONENTS: [f64; 3] = [0.5, 1.0, GAUSSIAN_STRIBECK_EXPONENT];
/// Sensor low-pass cutoffs searched, as multiples of the highest excitation frequency (the
/// member on every channel; first order).
pub const LOWPASS_CUTOFF_MULTIPLES: [f64; 9] = [0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0, 15.0];
/// Second-order cutoffs searched on every channel (damping ratio
/// [`LOWPASS_SECOND_ORDER_DAMPING`]): where a second-order filter differs from a first-order one
/// within the excitation band.
pub const LOWPASS_SECOND_ORDER_MULTIPLES: [f64; 5] = [1.0, 1.5, 2.0, 3.0, 4.0];
pub const LOWPASS_SECOND_ORDER_DAMPING: f64 = 0.7;
/// Series-compliance relaxation times searched (then refined, [`super::series::refine`]), as
/// multiples of 1 / (2 pi f_max): from a spring 50 times stiffer than the damper at the top
/// frequency to one 6 times softer.
pub const SERIES_RELAXATION_MULTIPLES: [f64; 12] = [
    0.02, 0.034, 0.057, 0.097, 0.16, 0.28, 0.47, 0.8, 1.35, 2.3, 3.9, 6.5,
];
/// Mass factors searched.
pub const MASS_FACTORS: [f64; 6] = [0.8, 0.9, 0.95, 1.05, 1.1, 1.25];

/// The values a candidate's nonlinear parameter is searched over, relative to the data's
/// [`Scales`]. The rig path searches [`SearchGrid::RIG`]; the time-domain path of a force-driven
/// axis has its own (its yield is relative to the position range, not an amplitude).
#[derive(Debug, Clone, Copy)]
pub struct SearchGrid {
    pub stribeck_velocity_fractions: &'static [f64],
    /// Searched with every Stribeck velocity; a single exponent is fixed, not searched (it is
    /// then neither counted as a parameter nor listed as searched).
    pub stribeck_exponents: &'static [f64],
    pub hysteresis_yield_fractions: &'static [f64],
    pub free_play_gap_fractions: &'static [f64],
    pub lowpass_cutoff_multiples: &'static [f64],
    pub mass_factors: &'static [f64],
    /// Series-compliance relaxation times c / ks, as multiples of 1 / (2 pi f_max).
    pub series_relaxation_multiples: &'static [f64],
}

impl SearchGrid {
    pub const RIG: SearchGrid = SearchGrid {
        stribeck_velocity_fractions: &STRIBECK_VELOCITY_FRACTIONS,
        stribeck_exponents: &STRIBECK_EXPONENTS,
        hysteresis_yield_fractions: &HYSTERESIS_YIELD_FRACTIONS,
        free_play_gap_fractions: &FREE_PLAY_GAP_FRACTIONS,
        lowpass_cutoff_multiples: &LOWPASS_CUTOFF_MULTIPLES,
        mass_factors: &MASS_FACTORS,
        series_relaxation_multiples: &SERIES_RELAXATION_MULTIPLES,
    };
}

/// The scales the searches are relative to.
#[derive(Debug, Clone, Copy)]
pub struct Scales {
    pub max_displacement_m: f64,
    pub max_velocity_mps: f64,
    pub max_frequency_hz: f64,
}

fn one(effect: Effect, terms: Vec<Arc<dyn Term>>) -> Structure {
    let n = terms.len();
    Structure {
        effects: vec![effect],
        terms,
        extra_parameters: n,
        ..Structure::default()
    }
}

/// Whether the baseline already holds the effect (then it is not a candidate).
pub fn baseline_has(baseline: &Model, effect: Effect) -> bool {
    let has = |sym: &str| baseline.terms.iter().any(|t| t.symbol() == sym);
    match effect {
        Effect::CoulombFriction => baseline.has_friction(),
        Effect::StribeckFriction => has("fs"),
        Effect::QuadraticDamping => has("c2"),
        Effect::CubicStiffness => has("s") || has("p30"),
        Effect::QuadraticStiffness => has("k2"),
        Effect::AsymmetricDamping => has("ca"),
        Effect::FreePlay => has("kfp"),
        Effect::Preload => has("offset"),
        _ => false,
    }
}

/// The structures to try for `effect` (one per value of its searched parameter) on the rig's
/// grid. Exciter delay has a closed-form estimate instead (see
/// `exciter::estimate_exciter_delay`), so it is built by the caller.
pub fn structures(baseline: &Model, effect: Effect, scales: &Scales) -> Vec<Structure> {
    structures_on(baseline, effect, scales, &SearchGrid::RIG)
}

/// [`structures`] searched over `grid`: the one place each effect's added terms are built, for
/// the rig's phasors and for time-domain records alike.
pub fn structures_on(
    baseline: &Model,
    effect: Effect,
    scales: &Scales,
    grid: &SearchGrid,
) -> Vec<Structure> {
    let has_friction = baseline.has_friction();
    match effect {
        Effect::CoulombFriction => vec![one(effect, vec![Arc::new(SignVelocity)])],
        Effect::StribeckFriction => {
            let exponent_searched = grid.stribeck_exponents.len() > 1;
            grid.stribeck_exponents
                .iter()
                .flat_map(|&exponent| {
                    grid.stribeck_velocity_fractions.iter().map(move |f| {
                        let law = StribeckVelocity {
                            velocity_mps: f * scales.max_velocity_mps,
                            exponent,
                        };
                        stribeck_structure(law, has_friction, exponent_searched)
                    })
                })
                .collect()
        }
        Effect::QuadraticDamping => vec![one(effect, vec![Arc::new(SignedSquareVelocity)])],
        Effect::CubicStiffness => vec![one(effect, vec![Arc::new(Cubic)])],
        Effect::QuadraticStiffness => vec![one(
            effect,
            vec![
                Arc::new(SignedSquareDisplacement),
                Arc::new(SquareDisplacement),
            ],
        )],
        Effect::AsymmetricDamping => vec![one(effect, vec![Arc::new(AbsVelocity)])],
        // The centred gaps; the search refines each contact point from the best of them
        // ([`super::free_play::refine`]).
        Effect::FreePlay => grid
            .free_play_gap_fractions
            .iter()
            .map(|f| {
                let half = 0.5 * f * scales.max_displacement_m;
                super::free_play::structure(half, half)
            })
            .collect(),
        Effect::Hysteresis => grid
            .hysteresis_yield_fractions
            .iter()
            .map(|f| {
                let zy = f * scales.max_displacement_m;
                hysteresis_structure(HysteresisLaw::yield_law(zy), false)
            })
            .collect(),
        // The member on every channel; the single-channel members are chosen by the channel
        // identities (`sensor::best_subset_member`, built by the caller with
        // [`sensor_structure`]).
        Effect::SensorLowpass => grid
            .lowpass_cutoff_multiples
            .iter()
            .map(|m| SensorFilter::first_order_on_all(m * scales.max_frequency_hz))
            .chain(LOWPASS_SECOND_ORDER_MULTIPLES.iter().map(|m| SensorFilter {
                order: 2,
                damping_ratio: LOWPASS_SECOND_ORDER_DAMPING,
                ..SensorFilter::first_order_on_all(m * scales.max_frequency_hz)
            }))
            .map(|f| sensor_structure(&f))
            .collect(),
        Effect::MassError => grid
            .mass_factors
            .iter()
            .map(|f| Structure {
                effects: vec![effect],
                transform: Transform {
                    mass_factor: *f,
                    ..Transform::default()
                },
                searched: vec![("mass_factor".into(), *f)],
                extra_parameters: 1,
                ..Structure::default()
            })
            .collect(),
        Effect::Preload => vec![one(effect, vec![Arc::new(Constant)])],
        // Both act on the baseline's damper c x'; without one they have nothing to act on.
        Effect::SeriesCompliance if has_damper(baseline) => grid
            .series_relaxation_multiples
            .iter()
            .map(|m| series_structure(m / (std::f64::consts::TAU * scales.max_frequency_hz)))
            .collect(),
        Effect::Drift if has_damper(baseline) => vec![Structure {
            effects: vec![effect],
            drift: true,
            extra_parameters: 1,
            ..Structure::default()
        }],
        Effect::SeriesCompliance | Effect::Drift | Effect::ExciterDelay => Vec::new(),
    }
}

/// Bouc-Wen shapes (n, r) searched at the best yield displacements of the one-parameter law
/// (n = 1, r = 1/2) ([`super::search`]): softer and sharper knees, symmetric and
/// loading-dominated loops; the wide forms' world plants n in 0.7-2.5 and r in 0.5-0.9.
pub const BOUC_WEN_SHAPES: [(f64, f64); 6] = [
    (1.0, 0.5),
    (0.75, 0.5),
    (2.0, 0.5),
    (1.0, 0.85),
    (0.75, 0.85),
    (2.0, 0.85),
];

/// The hysteresis structure of `law`: alpha and the yield are its parameters, and with
/// `shape_searched` (the member was chosen among [`BOUC_WEN_SHAPES`]) n and r too, reported as
/// searched values whatever member was chosen.
pub fn hysteresis_structure(law: HysteresisLaw, shape_searched: bool) -> Structure {
    let mut searched = vec![("yield_m".to_string(), law.yield_m)];
    if shape_searched {
        searched.push((bouc_wen::EXPONENT_NAME.into(), law.n));
        searched.push((bouc_wen::SHARE_NAME.into(), law.r));
    }
    Structure {
        effects: vec![Effect::Hysteresis],
        hysteresis: Some(law),
        searched,
        extra_parameters: if shape_searched { 4 } else { 2 },
        ..Structure::default()
    }
}

/// The name of the Stribeck shape exponent among a structure's searched parameters.
pub const STRIBECK_EXPONENT_NAME: &str = "stribeck_exponent";
/// The name of the Stribeck velocity among a structure's searched parameters.
pub const STRIBECK_VELOCITY_NAME: &str = "stribeck_velocity_mps";

/// The stribeck_friction structure of one law: the excess fs (with fd sgn(x') too when the
/// baseline has no friction), its velocity searched and, when `exponent_searched`, its shape
/// exponent (one more searched parameter).
pub fn stribeck_structure(
    law: StribeckVelocity,
    baseline_has_friction: bool,
    exponent_searched: bool,
) -> Structure {
    let mut terms: Vec<Arc<dyn Term>> = vec![Arc::new(law)];
    if !baseline_has_friction {
        terms.insert(0, Arc::new(SignVelocity));
    }
    let mut s = one(Effect::StribeckFriction, terms);
    s.extra_parameters += 1;
    s.searched
        .push((STRIBECK_VELOCITY_NAME.into(), law.velocity_mps));
    if exponent_searched {
        s.extra_parameters += 1;
        s.searched
            .push((STRIBECK_EXPONENT_NAME.into(), law.exponent));
    }
    s
}

/// The searched shape exponent of a stribeck_friction structure (None when it is not searched).
pub fn stribeck_exponent(s: &Structure) -> Option<f64> {
    s.searched
        .iter()
        .find(|(n, _)| n == STRIBECK_EXPONENT_NAME)
        .map(|(_, e)| *e)
}

/// Whether the baseline has the viscous damper `c x'` that series compliance and drift act on.
pub fn has_damper(baseline: &Model) -> bool {
    baseline
        .terms
        .iter()
        .any(|t| t.symbol() == super::series::DAMPER_SYMBOL)
}

/// The series_compliance structure with relaxation time `tau_s` = c / ks.
pub fn series_structure(tau_s: f64) -> Structure {
    Structure {
        effects: vec![Effect::SeriesCompliance],
        series_relaxation_s: Some(tau_s),
        searched: vec![("relaxation_s".into(), tau_s)],
        extra_parameters: 1,
        ..Structure::default()
    }
}

/// The sensor_lowpass structure of one member of the family.
pub fn sensor_structure(f: &SensorFilter) -> Structure {
    Structure {
        effects: vec![Effect::SensorLowpass],
        transform: Transform {
            sensor: Some(*f),
            ..Transform::default()
        },
        searched: f.searched(),
        extra_parameters: f.parameters(),
        ..Structure::default()
    }
}
