//! Identification of the element parameters theta from stepped-sine data.
//!
//! - `Method::Fd`: the paper's FD-FSM, first harmonic only (eqs. 12-17, 22, 23).
//! - `Method::FdMulti`: forcemap's improved FD-FSM, a weighted harmonic balance of every
//!   measured harmonic n = 0..N (eq. 11), each real equation weighted by that harmonic's
//!   measured noise plus the step's form error, where the model misses the step by more than
//!   its noise (`weights`: noisy high harmonics count little instead of being cut, and a form
//!   that is not the element's does not let the quietest harmonics decide). For models with
//!   a friction term (sgn or atan), the basis functions are balanced over the slip part of the cycle only; while the
//!   element sticks (or reverses) its force is set-valued, so there it is an unknown per step (a
//!   low-order polynomial per stick interval plus a jump where the element sticks or reverses),
//!   whose columns are projected out of the step's equations.
//! - `Method::OutputError`: fd-multi's estimate refined by output error against the exact model's
//!   simulation (stick-slip included) of the rig or the 3-DOF drive-point setup; see
//!   `output_error`.
//! - `Method::Td`: classical time-domain force-state mapping (paper section 4.3), the baseline.
//!
//! - A periodic multisine record gives one block of equations per record, one complex
//!   equation per excited line (`multisine`), stacked with the sine steps' blocks.
//!
//! Each step gives a block of equations (`StepEquations`); blocks are stacked and solved by
//! `lstsq::solve`. The live identifier node accumulates the same blocks.

mod accumulator;
mod cycle;
mod fd;
mod multisine;
mod output_error;
mod quality;
mod stick;
mod td;
mod weights;

pub use accumulator::EquationAccumulator;
pub use cycle::{Cycle, rebuilt_cycle};
pub use quality::{FORM_WARNING_RATIO, FitQuality, HarmonicBand};
pub use weights::{FORM_FACTOR, RowNoise};

pub use fd::{ElementHarmonics, element_harmonics, step_equations};
pub use multisine::{
    TermLag, accumulate_multisines, accumulate_multisines_lagged, identify_with_multisines,
    multisine_equations, multisine_equations_about, multisine_equations_about_lagged,
};
pub use output_error::{
    ElementOutputError, FORM_MAY_BE_WRONG, FORM_MISFIT_VARIANCE, HYSTERESIS_PARAMETERS,
    RecordsOutputError, RigChannelEffect, RigDrive, RigMisfit, RigOutputError, element_drive_of,
    records_drive, refine_output_error,
};
pub use td::{element_state_equations, td_range_equations, td_step_equations};

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::lstsq::LstsqError;
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;
use crate::record::Record;

/// Identification method. Its name ([`Method::name`], parsed back by `FromStr`) is its
/// serialised form: `fd`, `fd-multi`, `output-error`, `td-N`, `td-all`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Method {
    /// The paper's first-harmonic FD-FSM.
    Fd,
    /// All harmonics, slip-phase aware.
    FdMulti,
    /// `FdMulti`, then refined by output error against the exact model's simulation (rig and
    /// 3-DOF drive-point setups; a global post-step, not a per-step block producer).
    OutputError,
    /// Time-domain FSM; `points_per_step` None = every settled sample.
    Td { points_per_step: Option<usize> },
}

impl Method {
    pub fn name(&self) -> String {
        match self {
            Method::Fd => "fd".into(),
            Method::FdMulti => "fd-multi".into(),
            Method::OutputError => "output-error".into(),
            Method::Td {
                points_per_step: Some(n),
            } => format!("td-{n}"),
            Method::Td {
                points_per_step: None,
            } => "td-all".into(),
        }
    }
}

/// Time points per step of `td` when no number is given: the paper's 20.
pub const TD_POINTS_PER_STEP: usize = 20;

impl std::str::FromStr for Method {
    type Err = crate::recipe::RecipeError;

    fn from_str(name: &str) -> Result<Method, Self::Err> {
        let unknown = || crate::recipe::RecipeError::UnknownMethod(name.to_string());
        Ok(match name {
            "fd" => Method::Fd,
            "fd-multi" => Method::FdMulti,
            "output-error" => Method::OutputError,
            "td" => Method::Td {
                points_per_step: Some(TD_POINTS_PER_STEP),
            },
            "td-all" => Method::Td {
                points_per_step: None,
            },
            _ => {
                let n = name.strip_prefix("td-").ok_or_else(unknown)?;
                // Digits only: "td-+5" is not a method name.
                if !n.bytes().all(|b| b.is_ascii_digit()) {
                    return Err(unknown());
                }
                match n.parse::<usize>() {
                    Ok(n) if n > 0 => Method::Td {
                        points_per_step: Some(n),
                    },
                    _ => return Err(unknown()),
                }
            }
        })
    }
}

impl TryFrom<String> for Method {
    type Error = crate::recipe::RecipeError;

    fn try_from(name: String) -> Result<Method, Self::Error> {
        name.parse()
    }
}

impl From<Method> for String {
    fn from(m: Method) -> String {
        m.name()
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// How the improved method weights its real equations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Weighting {
    /// Each harmonic by the inverse of its measured noise plus the step's form error (the
    /// default): the noise weighting where the model explains a step within its noise, every
    /// harmonic alike where the model's form misses more than the noise (`weights`).
    #[default]
    Robust,
    /// Each harmonic by the inverse of its measured noise: noisy high harmonics count little,
    /// and the covariance is that of the measured scatter (at the Cramer-Rao bound of a model
    /// whose form is the element's).
    Noise,
    /// Every harmonic's equations in newtons, unweighted (for comparison, or when the records
    /// are too short for a noise estimate).
    Uniform,
}

impl Weighting {
    pub fn name(&self) -> &'static str {
        match self {
            Weighting::Robust => "robust",
            Weighting::Noise => "noise",
            Weighting::Uniform => "uniform",
        }
    }
}

impl std::fmt::Display for Weighting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Weighting {
    type Err = crate::recipe::RecipeError;

    fn from_str(name: &str) -> Result<Weighting, Self::Err> {
        match name {
            "robust" => Ok(Weighting::Robust),
            "noise" => Ok(Weighting::Noise),
            "uniform" => Ok(Weighting::Uniform),
            _ => Err(crate::recipe::RecipeError::UnknownWeighting(
                name.to_string(),
            )),
        }
    }
}

/// Tuning of the improved method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FdMultiOptions {
    /// Grid points per period at which the rebuilt waveforms are evaluated (rounded up to a
    /// power of two, at least 16 per harmonic).
    pub grid_points: usize,
    /// Samples with |x'| below this fraction of the step's peak |x'| are taken as stuck (or at
    /// a velocity reversal) and left out of the basis functions for models with a friction term.
    pub stick_velocity_fraction: f64,
    /// Margin around the stick intervals, in periods of the highest significant displacement
    /// harmonic (the resolution of the rebuilt velocity).
    pub guard_harmonic_periods: f64,
    /// Degree of the polynomial (per stick interval) that stands for the unknown element force
    /// while it sticks.
    pub stick_force_degree: usize,
    /// Directions of the stick-force polynomials with a singular value below this fraction of
    /// the largest are not projected out (they would need a huge stick force).
    pub stick_force_tolerance: f64,
    /// Where the force may jump inside a stick interval (stick onset or sign change of x') is
    /// located to within this many periods of the highest significant displacement harmonic.
    pub jump_margin_harmonic_periods: f64,
    /// Floor of each harmonic's force noise, relative to the first force harmonic, so that
    /// noise-free data are not weighted by round-off.
    pub noise_floor: f64,
    pub weighting: Weighting,
    /// A periodic multisine record also gives equations at the bins it does not excite where
    /// the displacement stands out of its noise (its nonlinear distortion; the force there is
    /// only what the element's nonlinearity makes, which ties the nonlinear terms), not only
    /// at the excited lines.
    pub multisine_distortion_lines: bool,
    /// An element test's moving mass as a first fit found it, where the mass is identified
    /// and the acceleration is the displacement differentiated: each harmonic's equation then
    /// carries the acceleration's noise times this mass, as a known mass's does. Without it,
    /// the noise of the differentiated displacement, amplified by (n w)^2 and carried by no
    /// row's weight, pulls the identified mass toward zero. [`identify`] sets it from the
    /// first-harmonic fit.
    pub moving_mass_hint_kg: Option<f64>,
}

impl Default for FdMultiOptions {
    fn default() -> Self {
        FdMultiOptions {
            grid_points: 1024,
            stick_velocity_fraction: 0.01,
            guard_harmonic_periods: 0.0,
            stick_force_degree: 3,
            stick_force_tolerance: 1e-6,
            jump_margin_harmonic_periods: 0.5,
            noise_floor: 1e-4,
            weighting: Weighting::default(),
            multisine_distortion_lines: true,
            moving_mass_hint_kg: None,
        }
    }
}

/// One block of real equations A theta = b from one step.
#[derive(Debug, Clone)]
pub struct StepEquations {
    pub step: usize,
    pub a: DMatrix<f64>,
    pub b: DVector<f64>,
    /// How many statistically independent real equations the rows stand for (rows of a
    /// rebuilt waveform are not independent: 2N+1 numbers made them).
    pub independent_equations: f64,
    /// Per-term RMS of h_i over the step's whole cycle (for the r contributions).
    pub term_rms: Vec<f64>,
    /// What a user should know about this step (e.g. left out because it never slipped).
    pub notes: Vec<String>,
    /// How each row's residual compares with its noise (empty: the rows are not equations of
    /// a harmonic with a noise estimate, as the time-domain method's and a multisine's).
    pub row_noise: Vec<RowNoise>,
    /// The form-error variance the step's rows were weighted with (0: none; `weights`).
    pub form_variance: f64,
}

#[derive(Debug, Error)]
pub enum IdentifyError {
    #[error("step {step}: {problem}")]
    Step { step: usize, problem: String },
    #[error("no usable stepped-sine steps in the data (need at least one settled sine step)")]
    NoSteps,
    #[error(transparent)]
    Lstsq(#[from] LstsqError),
    #[error(
        "tracking is step by step: method {0} does not give equations per step (use fd or fd-multi)"
    )]
    NotPerStep(String),
}

#[derive(Debug, Clone, Serialize)]
pub struct Parameter {
    pub name: String,
    pub value: f64,
    pub std: f64,
}

/// A warning about a solution that code acts on (the identifier node's WARN on /diagnostics), as
/// [`EquationAccumulator::solve_with_flags`] gives it; its Display is the warning's text in
/// [`Identification::warnings`], so callers decide by the kind rather than by the wording.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum IdentifyWarning {
    /// The column-scaled condition number is above [`crate::lstsq::WARN_CONDITION_NUMBER`];
    /// `text` is the least-squares solver's warning, which names the weakly determined
    /// parameters.
    BadlyConditioned { condition_number: f64, text: String },
    /// Fewer than twice as many independent real equations as parameters.
    FewEquations { independent: f64, parameters: usize },
    /// The residual is more than [`FORM_WARNING_RATIO`] times what the noise allows: the
    /// model's form is not the element's. `text` names the bands of harmonics.
    WrongForm {
        residual_to_noise: f64,
        text: String,
    },
}

impl std::fmt::Display for IdentifyWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IdentifyWarning::BadlyConditioned { text, .. } => f.write_str(text),
            IdentifyWarning::FewEquations {
                independent,
                parameters,
            } => write!(
                f,
                "few equations: {independent:.0} independent real equations for {parameters} parameters"
            ),
            IdentifyWarning::WrongForm { text, .. } => f.write_str(text),
        }
    }
}

/// The result of an identification.
#[derive(Debug, Clone, Serialize)]
pub struct Identification {
    pub model: String,
    pub method: String,
    pub parameters: Vec<Parameter>,
    pub covariance: Vec<Vec<f64>>,
    pub condition_number: f64,
    pub equations: usize,
    /// Share [%] of each term in the RMS transmitted force (the paper's r values).
    pub r: Vec<(String, f64)>,
    pub residual_rms: f64,
    /// Steps that contributed equations.
    pub steps_used: Vec<usize>,
    /// The residual against the noise, by band of harmonics (`None` where the equations are
    /// not of harmonics with a noise estimate: the time-domain method).
    pub fit_quality: Option<FitQuality>,
    /// The RMS of an output-error fit's residual in noise standard deviations (each compared
    /// sample over its channel's measured noise); `None` where the fit is not output error or
    /// the noise could not be measured.
    pub misfit_noise_std: Option<f64>,
    pub warnings: Vec<String>,
}

impl Identification {
    pub fn value(&self, name: &str) -> Option<f64> {
        self.parameters
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.value)
    }
    pub fn theta(&self) -> Vec<f64> {
        self.parameters.iter().map(|p| p.value).collect()
    }

    /// The values of the parameters `setup` added (after the model's, in the order of
    /// [`Setup::extra_parameters`]): an element test's identified moving mass.
    pub fn extra_values(&self, setup: &Setup) -> Vec<f64> {
        let n = setup.extra_parameters().len();
        self.parameters[self.parameters.len().saturating_sub(n)..]
            .iter()
            .map(|p| p.value)
            .collect()
    }
}

/// The moving mass of an element test whose mass is identified and whose acceleration is not
/// measured, from the first-harmonic fit of `analyses` (`fd`, where the displacement's
/// differentiated noise is small): [`FdMultiOptions::moving_mass_hint_kg`], which fd-multi's
/// identification of these steps takes (offline in [`identify`], live in the identifier
/// node). None where it does not apply or the fit gives no positive mass.
pub fn moving_mass_hint(
    model: &Model,
    setup: &Setup,
    analyses: &[HarmonicAnalysis],
    options: &FdMultiOptions,
) -> Option<f64> {
    let derived = analyses.iter().any(|an| {
        an.channel(crate::record::Channel::MassAccelerationMps2)
            .is_none()
    });
    if !matches!(
        setup,
        Setup::Element {
            moving_mass_kg: None,
            ..
        }
    ) || !derived
    {
        return None;
    }
    let first = identify(model, setup, Method::Fd, &[], analyses, options).ok()?;
    first
        .extra_values(setup)
        .first()
        .copied()
        .filter(|m| m.is_finite() && *m > 0.0)
}

/// Stacks step blocks and solves (through the same accumulator the live identifier keeps, so
/// both agree exactly). Blocks may be weighted already.
pub fn solve_blocks(
    model: &Model,
    setup: &Setup,
    method: Method,
    blocks: &[StepEquations],
) -> Result<Identification, IdentifyError> {
    let mut acc = EquationAccumulator::new(model, setup, method);
    for blk in blocks {
        acc.add(blk)?;
    }
    acc.solve()
}

/// Theta after each step, the steps before it weighed by `factor_per_step` each time a step is
/// added (exponential forgetting; 1 gives the converged theta after each step): what the live
/// identifier publishes step by step when it tracks. Per-step methods only (fd, fd-multi);
/// steps before the equations determine theta give none.
pub fn track_steps(
    model: &Model,
    setup: &Setup,
    method: Method,
    analyses: &[HarmonicAnalysis],
    options: &FdMultiOptions,
    factor_per_step: f64,
) -> Result<Vec<Identification>, IdentifyError> {
    let steps: Vec<TrackedStep> = analyses
        .iter()
        .map(|an| TrackedStep {
            provisional: &[],
            last: an,
        })
        .collect();
    Ok(
        track_steps_within(model, setup, method, &steps, options, factor_per_step)?
            .into_iter()
            .map(|t| t.identification)
            .collect(),
    )
}

/// One step to track: the provisional analyses of its samples so far, in order
/// ([`provisional_analyses`](crate::phasor::provisional_analyses)), and its final one.
#[derive(Debug, Clone, Copy)]
pub struct TrackedStep<'a> {
    pub provisional: &'a [HarmonicAnalysis],
    pub last: &'a HarmonicAnalysis,
}

/// A theta of a track and the data it describes.
#[derive(Debug, Clone)]
pub struct TrackPoint {
    pub identification: Identification,
    /// The newest step in it.
    pub step: usize,
    /// Whether that step was provisional (its samples so far).
    pub provisional: bool,
    /// The end of the data it includes [s since the start of the run]: the end of the newest
    /// step's last fitted period ([`HarmonicAnalysis::data_end_s`]).
    pub data_end_s: f64,
}

/// [`track_steps`] with updates within each step: each provisional analysis is solved with the
/// steps before it ([`EquationAccumulator::with_provisional`], as the live identifier does) and
/// then replaced by the next or by the step's final analysis, which is added for good.
pub fn track_steps_within(
    model: &Model,
    setup: &Setup,
    method: Method,
    steps: &[TrackedStep],
    options: &FdMultiOptions,
    factor_per_step: f64,
) -> Result<Vec<TrackPoint>, IdentifyError> {
    if !matches!(method, Method::Fd | Method::FdMulti) {
        return Err(IdentifyError::NotPerStep(method.name()));
    }
    let mut acc = EquationAccumulator::new(model, setup, method);
    let mut out = Vec::new();
    for st in steps {
        for an in st.provisional {
            let blk = step_equations(model, setup, method, an, options)?;
            let solved = acc.with_provisional(factor_per_step, &blk)?.solve();
            if let Some(id) = determined(solved)? {
                out.push(TrackPoint {
                    identification: id,
                    step: an.step,
                    provisional: true,
                    data_end_s: an.data_end_s(),
                });
            }
        }
        let blk = step_equations(model, setup, method, st.last, options)?;
        acc.forget(factor_per_step);
        acc.add(&blk)?;
        if let Some(id) = determined(acc.solve())? {
            out.push(TrackPoint {
                identification: id,
                step: st.last.step,
                provisional: false,
                data_end_s: st.last.data_end_s(),
            });
        }
    }
    Ok(out)
}

/// A solve's theta, `None` while the equations do not determine it yet.
fn determined(
    solved: Result<Identification, IdentifyError>,
) -> Result<Option<Identification>, IdentifyError> {
    match solved {
        Ok(id) => Ok(Some(id)),
        Err(IdentifyError::Lstsq(
            LstsqError::Underdetermined { .. } | LstsqError::IllConditioned { .. },
        )) => Ok(None),
        Err(e) => Err(e),
    }
}

/// Identifies `model` from stepped-sine steps. FD methods use the harmonic analyses; TD uses the
/// records (and the analyses for the settled part).
pub fn identify(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
    analyses: &[HarmonicAnalysis],
    options: &FdMultiOptions,
) -> Result<Identification, IdentifyError> {
    if method == Method::OutputError {
        let first = identify(model, setup, Method::FdMulti, records, analyses, options)?;
        return refine_output_error(model, setup, records, analyses, &first);
    }
    if method == Method::FdMulti
        && options.moving_mass_hint_kg.is_none()
        && let Some(hint) = moving_mass_hint(model, setup, analyses, options)
    {
        let hinted = FdMultiOptions {
            moving_mass_hint_kg: Some(hint),
            ..*options
        };
        return identify(model, setup, method, records, analyses, &hinted);
    }
    let mut blocks = Vec::with_capacity(analyses.len());
    for an in analyses {
        let blk = match method {
            Method::Fd | Method::FdMulti => step_equations(model, setup, method, an, options)?,
            Method::OutputError => unreachable!("handled above"),
            Method::Td { points_per_step } => {
                let rec = records.iter().find(|r| r.step == an.step).ok_or_else(|| {
                    IdentifyError::Step {
                        step: an.step,
                        problem: "no samples for this step (time-domain FSM needs the samples)"
                            .into(),
                    }
                })?;
                td_step_equations(model, setup, rec, an, points_per_step)?
            }
        };
        blocks.push(blk);
    }
    solve_blocks(model, setup, method, &blocks)
}
