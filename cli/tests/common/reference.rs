//! The plain reference the real-data suite and the form-error tests score forcemap against:
//! the time-domain least squares of a model's terms (and the moving mass) on every scored
//! sample of the fitted records, solved by nalgebra's SVD (independent of forcemap's
//! solvers). The states are those `--validate` predicts along (`MeasuredState`: the velocity and
//! acceleration differentiated in the frequency domain, the ends of each record left out), so
//! both are scored on the same samples.

use forcemap_math::measured_state::MeasuredState;
use forcemap_math::model::Model;
use forcemap_math::pipeline::nmse_percent;
use forcemap_math::record::Record;

/// A state column of a record: one value per sample of its measured state (a hysteresis
/// state integrated along its measured velocity), appended to each row.
pub type StateColumn<'a> = &'a dyn Fn(&MeasuredState) -> Vec<f64>;

/// A record's regressor rows (each term at the state, then the acceleration if `with_mass`,
/// then `column`'s value) and its measured force, over its scored samples.
fn rows(
    model: &Model,
    with_mass: bool,
    column: Option<StateColumn>,
    r: &Record,
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let s = MeasuredState::of(r).expect("a record's held-out states");
    let extra = column.map(|c| c(&s));
    s.scored
        .clone()
        .map(|i| {
            let (x, v) = (s.displacement_m[i], s.velocity_mps[i]);
            let mut row: Vec<f64> = model.terms.iter().map(|t| t.eval(x, v)).collect();
            if with_mass {
                row.push(s.acceleration_mps2[i]);
            }
            if let Some(z) = &extra {
                row.push(z[i]);
            }
            (row, s.force_n[i])
        })
        .unzip()
}

/// The least-squares theta of `model`'s terms (then the moving mass, if `with_mass`) on every
/// scored sample of `fit`.
pub fn least_squares_theta(model: &Model, with_mass: bool, fit: &[Record]) -> Vec<f64> {
    least_squares_theta_with(model, with_mass, None, fit)
}

/// [`least_squares_theta`] with a state column's coefficient last.
pub fn least_squares_theta_with(
    model: &Model,
    with_mass: bool,
    column: Option<StateColumn>,
    fit: &[Record],
) -> Vec<f64> {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for r in fit {
        let (rr, f) = rows(model, with_mass, column, r);
        a.extend(rr);
        b.extend(f);
    }
    let p = model.terms.len() + usize::from(with_mass) + usize::from(column.is_some());
    let m = nalgebra::DMatrix::from_fn(a.len(), p, |i, j| a[i][j]);
    let theta = m
        .svd(true, true)
        .solve(&nalgebra::DVector::from_column_slice(&b), 1e-12)
        .expect("an SVD with both factors solves");
    theta.iter().copied().collect()
}

/// The held-out force NMSE [%] of `theta` (as [`least_squares_theta`] orders it) on each record.
pub fn nmse_on(model: &Model, theta: &[f64], held: &[Record]) -> Vec<f64> {
    nmse_on_with(model, theta, None, held)
}

/// [`nmse_on`] of a theta of [`least_squares_theta_with`].
pub fn nmse_on_with(
    model: &Model,
    theta: &[f64],
    column: Option<StateColumn>,
    held: &[Record],
) -> Vec<f64> {
    let with_mass = theta.len() > model.terms.len() + usize::from(column.is_some());
    held.iter()
        .map(|r| {
            let (rr, f) = rows(model, with_mass, column, r);
            let predicted: Vec<f64> = rr
                .iter()
                .map(|row| row.iter().zip(theta).map(|(h, t)| h * t).sum())
                .collect();
            nmse_percent(&f, &predicted)
        })
        .collect()
}
