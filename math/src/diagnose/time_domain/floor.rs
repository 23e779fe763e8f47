//! The floor of the verdict: the flexible memoryless force laws (module docs of [`super`],
//! "Floor").

use super::model::relative_error;
use super::preprocess::{Motion, Prepared};

/// The flexible memoryless force laws of the motion, `M q'' + g(q, q')`, that set the floor
/// of the verdict (see the docs of [`super`], "Floor"): `g` piecewise linear in the velocity
/// with enough knots for a Stribeck dip and a friction law that differs forwards and back (a
/// free jump at q' = 0), that law's shape varying with the position as a polynomial of a member's degree,
/// plus a piecewise-linear force of the position alone over a member's number of intervals of
/// the travel (none for 0). More freedom is not always a lower validation error (it is fitted
/// to the fitting record's noise and peculiarities too), so the floor takes the best member of
/// the family: degrees 0 to [`FlexibleLaws::MAX_POSITION_DEGREE`] times
/// [`FlexibleLaws::POSITION_INTERVALS`]. The geometry (knots, travel) comes from the fitting
/// record.
#[derive(Debug, Clone)]
pub(super) struct FlexibleLaws {
    /// Knots of the velocity hats per direction, from 0 to the peak speed of that direction
    /// on the fitting record, quadratically spaced (denser at low speed) [m/s].
    knots_forward_mps: Vec<f64>,
    knots_back_mps: Vec<f64>,
    /// Travel of the fitting record [m].
    q_min_m: f64,
    q_max_m: f64,
}

/// One member of [`FlexibleLaws`].
#[derive(Debug, Clone, Copy)]
pub(super) struct FlexibleMember {
    position_degree: usize,
    /// Index into [`FlexibleLaws::POSITION_INTERVALS`].
    resolution: usize,
}

impl FlexibleMember {
    fn position_intervals(self) -> usize {
        FlexibleLaws::POSITION_INTERVALS[self.resolution]
    }

    fn column_count(self) -> usize {
        1 + 2 * (FlexibleLaws::VELOCITY_INTERVALS + 1) * (self.position_degree + 1)
            + self.position_intervals()
    }

    pub(super) fn describe(self) -> String {
        format!(
            "M q'' + g(q, q') with g piecewise linear in q' ({} intervals each way, free jump at q' = 0), its shape of degree {} in q, plus a piecewise-linear force of q over {} intervals of the travel ({} columns)",
            FlexibleLaws::VELOCITY_INTERVALS,
            self.position_degree,
            self.position_intervals(),
            self.column_count()
        )
    }
}

/// The decimated columns of every member of [`FlexibleLaws`] on one record, each computed
/// once (the members share most of them).
struct FlexibleColumns {
    acceleration: Vec<f64>,
    /// Per direction and knot: the velocity hat times the Legendre polynomials P0, P1, P2 of
    /// the scaled position.
    velocity: Vec<Vec<Vec<f64>>>,
    /// Per resolution: the position hats (the first left out, since the velocity hats of both
    /// directions already sum to one).
    position: Vec<Vec<Vec<f64>>>,
}

impl FlexibleColumns {
    fn member(&self, m: FlexibleMember) -> Vec<&[f64]> {
        let mut cols: Vec<&[f64]> = vec![&self.acceleration];
        for per_degree in &self.velocity {
            cols.extend(per_degree[..=m.position_degree].iter().map(Vec::as_slice));
        }
        cols.extend(self.position[m.resolution].iter().map(Vec::as_slice));
        cols
    }
}

impl FlexibleLaws {
    const VELOCITY_INTERVALS: usize = 10;
    const MAX_POSITION_DEGREE: usize = 2;
    const POSITION_INTERVALS: [usize; 4] = [0, 20, 40, 80];
    pub(super) const MEMBERS: usize =
        (Self::MAX_POSITION_DEGREE + 1) * Self::POSITION_INTERVALS.len();

    fn members() -> impl Iterator<Item = FlexibleMember> {
        (0..=Self::MAX_POSITION_DEGREE).flat_map(|d| {
            (0..Self::POSITION_INTERVALS.len()).map(move |r| FlexibleMember {
                position_degree: d,
                resolution: r,
            })
        })
    }

    /// Columns of the largest member.
    pub(super) fn max_columns() -> usize {
        Self::members()
            .map(FlexibleMember::column_count)
            .max()
            .unwrap_or(1)
    }

    fn new(fit: &Motion) -> FlexibleLaws {
        let peak = |sign: f64| {
            fit.qd
                .iter()
                .map(|v| v * sign)
                .fold(0.0f64, f64::max)
                .max(1e-9)
        };
        let knots = |peak: f64| {
            (0..=Self::VELOCITY_INTERVALS)
                .map(|k| peak * (k as f64 / Self::VELOCITY_INTERVALS as f64).powi(2))
                .collect()
        };
        let (lo, hi) = fit
            .q
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), q| {
                (l.min(*q), h.max(*q))
            });
        FlexibleLaws {
            knots_forward_mps: knots(peak(1.0)),
            knots_back_mps: knots(peak(-1.0)),
            q_min_m: lo,
            q_max_m: hi.max(lo + 1e-9),
        }
    }

    /// Every member's columns on a record, decimated. Outside the fitting record's travel the
    /// position is clamped to it; beyond its peak speeds the velocity hats extrapolate
    /// linearly.
    fn columns(&self, m: &Motion) -> FlexibleColumns {
        let scaled: Vec<f64> = m
            .q
            .iter()
            .map(|q| {
                (2.0 * (q - self.q_min_m) / (self.q_max_m - self.q_min_m) - 1.0).clamp(-1.0, 1.0)
            })
            .collect();
        let legendre = [|_: f64| 1.0, |x: f64| x, |x: f64| 1.5 * x * x - 0.5];
        let mut velocity = Vec::new();
        for (sign, knots) in [(1.0, &self.knots_forward_mps), (-1.0, &self.knots_back_mps)] {
            for k in 0..knots.len() {
                let h: Vec<f64> =
                    m.qd.iter()
                        .map(|v| {
                            let s = v * sign;
                            if s <= 0.0 { 0.0 } else { hat(knots, k, s) }
                        })
                        .collect();
                velocity.push(
                    legendre
                        .iter()
                        .map(|p| {
                            let full: Vec<f64> =
                                h.iter().zip(&scaled).map(|(h, x)| h * p(*x)).collect();
                            m.decimate(&full)
                        })
                        .collect(),
                );
            }
        }
        let position = Self::POSITION_INTERVALS
            .iter()
            .map(|&intervals| {
                let grid: Vec<f64> = (0..=intervals)
                    .map(|k| -1.0 + 2.0 * k as f64 / intervals as f64)
                    .collect();
                (1..grid.len())
                    .map(|k| {
                        let full: Vec<f64> = scaled.iter().map(|x| hat(&grid, k, *x)).collect();
                        m.decimate(&full)
                    })
                    .collect()
            })
            .collect();
        FlexibleColumns {
            acceleration: m.decimate(&m.qdd),
            velocity,
            position,
        }
    }
}

/// The piecewise-linear hat of knot `k` at `x`; beyond the last knot the last two hats
/// extrapolate linearly.
fn hat(knots: &[f64], k: usize, x: f64) -> f64 {
    let last = knots.len() - 1;
    if x >= knots[last] {
        let t = (x - knots[last - 1]) / (knots[last] - knots[last - 1]);
        return match last - k {
            0 => t,
            1 => 1.0 - t,
            _ => 0.0,
        };
    }
    let left = if k > 0 { knots[k - 1] } else { f64::NAN };
    let right = if k < last { knots[k + 1] } else { f64::NAN };
    if k > 0 && x > left && x <= knots[k] {
        (x - left) / (knots[k] - left)
    } else if k < last && x >= knots[k] && x < right {
        (right - x) / (right - knots[k])
    } else if x == knots[k] {
        1.0
    } else {
        0.0
    }
}

/// The member of the flexible family with the smallest validation error, and its relative
/// force error on the fitting and the validation record [%] (NaN when no member could be
/// solved).
pub(super) fn best_flexible_law(fit: &Prepared, val: &Prepared) -> (FlexibleMember, f64, f64) {
    let laws = FlexibleLaws::new(&fit.motion);
    let (fit_cols, val_cols) = (laws.columns(&fit.motion), laws.columns(&val.motion));
    let mut best: Option<(FlexibleMember, f64, f64)> = None;
    for member in FlexibleLaws::members() {
        let (f, v) = flexible_errors(&fit_cols.member(member), fit, &val_cols.member(member), val);
        if v.is_finite() && best.as_ref().is_none_or(|b| v < b.2) {
            best = Some((member, f, v));
        }
    }
    best.unwrap_or((
        FlexibleMember {
            position_degree: 0,
            resolution: 0,
        },
        f64::NAN,
        f64::NAN,
    ))
}

/// Fits one flexible law on the fitting record (minimum-norm least squares on the
/// column-scaled equations: its columns are not all independent, and only its force matters)
/// and returns its relative force error on the fitting and the validation record [%].
fn flexible_errors(
    fit_cols: &[&[f64]],
    fit: &Prepared,
    val_cols: &[&[f64]],
    val: &Prepared,
) -> (f64, f64) {
    let rows = fit.force.len();
    let scale: Vec<f64> = fit_cols
        .iter()
        .map(|c| {
            let n = c.iter().map(|v| v * v).sum::<f64>().sqrt();
            if n > 0.0 { n } else { 1.0 }
        })
        .collect();
    let a = nalgebra::DMatrix::from_fn(rows, fit_cols.len(), |r, c| fit_cols[c][r] / scale[c]);
    let b = nalgebra::DVector::from_column_slice(&fit.force);
    let svd = a.svd(true, true);
    let tol = 1e-10 * svd.singular_values.max();
    let Ok(theta_scaled) = svd.solve(&b, tol) else {
        return (f64::NAN, f64::NAN);
    };
    let theta: Vec<f64> = (0..fit_cols.len())
        .map(|j| theta_scaled[j] / scale[j])
        .collect();
    let prediction = |cols: &[&[f64]], n: usize| -> Vec<f64> {
        (0..n)
            .map(|i| cols.iter().zip(&theta).map(|(c, t)| c[i] * t).sum())
            .collect()
    };
    (
        relative_error(&fit.force, &prediction(fit_cols, rows)),
        relative_error(&val.force, &prediction(val_cols, val.force.len())),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hats_interpolate_and_extrapolate_linearly() {
        let knots = [0.0, 1.0, 4.0];
        let f = |x: f64| 2.0 + 3.0 * x;
        for x in [0.0, 0.5, 1.0, 2.5, 4.0, 6.0] {
            let v: f64 = (0..3).map(|k| f(knots[k]) * hat(&knots, k, x)).sum();
            assert!((v - f(x)).abs() < 1e-12, "{x}: {v}");
        }
    }
}
