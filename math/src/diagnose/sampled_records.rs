//! An element test's records with no steps (band-random, ramped sines, an earthquake history,
//! a whole file as one record) in the block diagnosis ([`super::multisine`]): each record's
//! equations are the time-domain rows of the element force along its measured motion
//! (`identify::element_state_equations`, every scored sample), the rows the identification fits
//! such records with, written from the record's measured state taken once, weighted by the measured force's noise so that a residual reads in units of
//! the noise as on the sine steps' and the multisines' equations.
//!
//! The force's noise is estimated from its spectrum above the band the derivatives are taken
//! in ([`crate::measured_state`]); white there, it makes each sample an independent real
//! equation. The rows are scaled to a noise variance of 1/2: the block sums count half an
//! independent real equation of noise per equation (a complex equation weighted to unit noise
//! is two). Where the element's force has content of its own above the band (a friction's
//! jumps), that content counts as noise: the floor is then high, which makes "explained"
//! harder, not easier.
//!
//! A base-excited rig's records with no steps are the element between base and mass seen the
//! same way ([`element_view_of_rig`]): its force is what holds the mass, -m a_o, along the
//! relative motion, with no moving mass of its own.
//!
//! A hysteresis candidate is fitted here too: its Bouc-Wen state integrated along the
//! record's measured velocity from the record's start (the unscored guard lets it forget its
//! start) is one more column, its coefficient alpha, as in the time-domain axis path.

use nalgebra::DMatrix;

use super::DiagnoseError;
use crate::identify::{IdentifyError, StepEquations, element_state_equations};
use crate::measured_state::{CUTOFF_MULTIPLE, MeasuredState, noise_std};
use crate::model::Model;
use crate::recipe::Setup;
use crate::record::{Channel, Record};
use crate::signal::bouc_wen::HysteresisLaw;

/// A base-excited rig's record as an element test of the element between base and mass: the
/// relative displacement, and as the force the one that holds the mass `mass_kg`, -m a_o
/// (m a_o + g(x, x') = 0), so that the element force g is fitted with no moving mass
/// (`Setup::Element` with a moving mass of 0). Err names the missing channel.
pub fn element_view_of_rig(record: &Record, mass_kg: f64) -> Result<Record, DiagnoseError> {
    let channel = |c: Channel| {
        record.channel(c).ok_or_else(|| {
            DiagnoseError::NotRig(format!(
                "record {} has no channel {} (the rig's records need the relative displacement and the mass acceleration)",
                record.step,
                c.name()
            ))
        })
    };
    let x = channel(Channel::RelativeDisplacementM)?;
    let a = channel(Channel::MassAccelerationMps2)?;
    Ok(Record {
        step: record.step,
        excitation: record.excitation.clone(),
        sample_rate_hz: record.sample_rate_hz,
        start_time_s: record.start_time_s,
        channels: vec![
            (Channel::RelativeDisplacementM, x.to_vec()),
            (Channel::ForceN, a.iter().map(|a| -mass_kg * a).collect()),
        ],
    })
}

/// A record fitted sample by sample: its measured state, and what its rows are weighted and
/// scaled by.
#[derive(Debug, Clone)]
pub struct SampledRecord {
    /// The record's measured state: the rows' states, and the velocity the hysteresis state is
    /// integrated along.
    pub state: MeasuredState,
    /// The measured force's noise std [N].
    pub force_noise_n: f64,
    /// The noise std the rows are scaled by [N]: the record's own ([`Self::new`]), or one
    /// shared by every record ([`pool_row_noise`]).
    pub row_noise_n: f64,
    /// The largest displacement from its mean [m] and velocity [m/s] over the scored samples.
    pub max_displacement_m: f64,
    pub max_velocity_mps: f64,
}

impl SampledRecord {
    /// `record` (relative displacement and force) with its force noise and scales.
    pub fn new(record: &Record) -> Result<SampledRecord, DiagnoseError> {
        let state = MeasuredState::of(record)?;
        let scored = state.scored.clone();
        let x = &state.displacement_m[scored.clone()];
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let peak = |y: &mut dyn Iterator<Item = f64>| y.fold(0.0f64, |m, v| m.max(v.abs()));
        let max_displacement_m = peak(&mut x.iter().map(|v| v - mean));
        let max_velocity_mps = peak(&mut state.velocity_mps[scored].iter().copied());
        let force_noise_n = noise_std(
            &state.force_n,
            state.sample_rate_hz,
            CUTOFF_MULTIPLE * state.top_frequency_hz,
        );
        Ok(SampledRecord {
            force_noise_n,
            row_noise_n: force_noise_n,
            max_displacement_m,
            max_velocity_mps,
            state,
        })
    }

    pub fn step(&self) -> usize {
        self.state.step
    }

    /// The highest excitation frequency the derivatives were taken for [Hz].
    pub fn top_frequency_hz(&self) -> f64 {
        self.state.top_frequency_hz
    }

    /// The hysteresis state of `law` along the record's measured velocity, every sample.
    pub fn hysteresis_state(&self, law: &HysteresisLaw) -> Vec<f64> {
        law.integrate_record(&self.state.velocity_mps, 1.0 / self.state.sample_rate_hz)
    }

    /// The record's equations for `model` on `setup` (an element test), with `hysteresis`'s
    /// state as a last column, weighted as the module docs say.
    pub(super) fn equations(
        &self,
        model: &Model,
        setup: &Setup,
        hysteresis: Option<&HysteresisLaw>,
    ) -> Result<StepEquations, DiagnoseError> {
        let Setup::Element { moving_mass_kg, .. } = setup else {
            return Err(IdentifyError::Step {
                step: self.step(),
                problem: format!(
                    "a record fitted on its samples is an element test's; this setup is {}",
                    setup.kind()
                ),
            }
            .into());
        };
        let n = self.state.force_n.len();
        let mut b = element_state_equations(model, *moving_mass_kg, &self.state, 0, n, None)?;
        if let Some(law) = hysteresis {
            // The rows are the scored samples, in order (every sample of the scored part).
            let z = self.hysteresis_state(law);
            let z = &z[self.state.scored.clone()];
            debug_assert_eq!(z.len(), b.a.nrows());
            let p = b.a.ncols();
            let a = std::mem::replace(&mut b.a, DMatrix::zeros(0, 0));
            let mut a = a.insert_column(p, 0.0);
            a.column_mut(p).copy_from_slice(z);
            b.a = a;
            b.term_rms
                .push((z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt());
        }
        let w = 1.0 / (std::f64::consts::SQRT_2 * self.row_noise_n);
        b.a *= w;
        b.b *= w;
        Ok(b)
    }
}

/// Every record's rows scaled by one noise std, the pooled one (the root of the noise
/// variances averaged over the scored samples): each sample then weighs alike, as in the plain
/// least squares of the force, and the noise the rows hold summed over every record is still
/// that of a variance of 1/2 per row, so the cross-validated noise floor stays the force
/// noise's. An identification of a model whose form is not the element's fits so: weighted by
/// their own noise, the records whose force is quietest decide the fit whatever their form
/// error.
pub fn pool_row_noise(records: &mut [SampledRecord]) {
    let (mut variance_sum, mut rows) = (0.0, 0usize);
    for r in records.iter() {
        let n = r.state.scored.len();
        variance_sum += n as f64 * r.force_noise_n * r.force_noise_n;
        rows += n;
    }
    if rows == 0 {
        return;
    }
    let pooled = (variance_sum / rows as f64).sqrt();
    for r in records {
        r.row_noise_n = pooled;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ModelOptions;
    use crate::record::{Channel, Excitation};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A linear element (k 2000 N/m, c 50 N s/m) driven at 2 and 5 Hz, its force with white
    /// noise of 0.5 N: the weighted rows of the true theta leave the noise, at variance 1/2
    /// per row within 5 % (10 000 rows: the estimate's own scatter is about 1.4 %), and the
    /// noise is measured within 5 %.
    #[test]
    fn the_rows_read_in_units_of_the_force_noise() {
        let (fs, n, sigma) = (500.0, 10_000, 0.5);
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let noise = Normal::new(0.0, sigma).unwrap();
        let (w1, w2) = (std::f64::consts::TAU * 2.0, std::f64::consts::TAU * 5.0);
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                0.01 * (w1 * t).sin() + 0.004 * (w2 * t).cos()
            })
            .collect();
        let f: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                let v = 0.01 * w1 * (w1 * t).cos() - 0.004 * w2 * (w2 * t).sin();
                2000.0 * x[i] + 50.0 * v + noise.sample(&mut rng)
            })
            .collect();
        let record = Record {
            step: 3,
            excitation: Excitation::UNKNOWN,
            sample_rate_hz: fs,
            start_time_s: 0.0,
            channels: vec![(Channel::RelativeDisplacementM, x), (Channel::ForceN, f)],
        };
        let r = SampledRecord::new(&record).unwrap();
        assert!(
            (r.force_noise_n / sigma - 1.0).abs() < 0.05,
            "{}",
            r.force_noise_n
        );
        let model = Model::by_name("linear", &ModelOptions::default()).unwrap();
        let setup = Setup::Element {
            moving_mass_kg: Some(0.0),
            drive: None,
        };
        let b = r.equations(&model, &setup, None).unwrap();
        let symbols: Vec<String> = model.terms.iter().map(|t| t.symbol()).collect();
        let theta: Vec<f64> = symbols
            .iter()
            .map(|s| match s.as_str() {
                "k" => 2000.0,
                "c" => 50.0,
                _ => 0.0,
            })
            .collect();
        let residual = &b.a * nalgebra::DVector::from_vec(theta) - &b.b;
        let per_row = residual.norm_squared() / b.independent_equations;
        assert!((per_row / 0.5 - 1.0).abs() < 0.05, "{per_row}");
        assert_eq!(b.a.nrows() as f64, b.independent_equations);
        // The same rows the identification fits, scaled.
        let plain =
            crate::identify::td_range_equations(&model, &setup, &record, 0, record.len(), None)
                .unwrap();
        let w = 1.0 / (std::f64::consts::SQRT_2 * r.force_noise_n);
        assert!((b.b[10] - w * plain.b[10]).abs() < 1e-12 * plain.b[10].abs().max(1.0));
    }
}
