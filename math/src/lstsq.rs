//! Least squares A theta = b by SVD of the column-scaled matrix (eq. 17 without forming the
//! normal equations), with the diagnostics an engineer needs to trust the answer.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Above this condition number (of the column-scaled matrix) the system is refused.
pub const MAX_CONDITION_NUMBER: f64 = 1e10;
/// Above this condition number the solution is returned with a warning.
pub const WARN_CONDITION_NUMBER: f64 = 1e6;

#[derive(Debug, Error, PartialEq)]
pub enum LstsqError {
    #[error(
        "{equations} real equations for {parameters} parameters ({names}): need at least as many equations as parameters; add steps (frequencies or amplitudes)"
    )]
    Underdetermined {
        equations: usize,
        parameters: usize,
        names: String,
    },
    #[error(
        "the equations cannot identify {names}: condition number {condition:.3e} (limit {limit:.0e}); these data do not excite them independently of the other terms"
    )]
    IllConditioned {
        condition: f64,
        limit: f64,
        names: String,
    },
    #[error(
        "non-finite value in the equations (row {row}): the measurements or phasors hold NaN or infinity"
    )]
    NonFinite { row: usize },
}

/// The least-squares solution and its statistics.
#[derive(Debug, Clone)]
pub struct Solution {
    pub theta: Vec<f64>,
    /// Covariance of theta: s^2 (A^T A)^-1 with s^2 the residual variance, times `variance_scale`.
    pub covariance: DMatrix<f64>,
    /// Condition number of A after scaling its columns to unit norm: the conditioning of the
    /// parameters themselves, independent of their units.
    pub condition_number: f64,
    pub equations: usize,
    /// RMS of the (weighted) residual A theta - b.
    pub residual_rms: f64,
    pub warnings: Vec<String>,
}

impl Solution {
    pub fn std(&self) -> Vec<f64> {
        (0..self.theta.len())
            .map(|i| self.covariance[(i, i)].max(0.0).sqrt())
            .collect()
    }
}

/// Solves min |A theta - b| by SVD. `names` label the columns in errors. `variance_scale`
/// corrects the covariance when rows are not independent equations (1 when they are).
pub fn solve(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    names: &[String],
    variance_scale: f64,
) -> Result<Solution, LstsqError> {
    assert_eq!(a.ncols(), names.len(), "one name per column");
    let mut acc = QrAccumulator::new(a.ncols());
    acc.add_rows(a, b)?;
    acc.solve(names, variance_scale)
}

/// The equations A theta = b seen so far, kept as the triangular factor of their QR
/// decomposition: `R` (at most p x p), `Q^T b`, and the residual sum of squares that no theta
/// can remove. Memory is O(p^2) however many rows are added, and adding rows in the same order
/// gives the same numbers bit for bit, which is what lets the live identifier agree exactly
/// with an offline run on the same data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QrAccumulator {
    cols: usize,
    /// Rows of `r` (min(rows, cols)).
    r_rows: usize,
    /// The upper-trapezoidal factor, row-major, `r_rows x cols`.
    r: Vec<f64>,
    /// The first `r_rows` components of Q^T b.
    qtb: Vec<f64>,
    /// Sum of squares of the other components of Q^T b.
    rss_outside: f64,
    rows: usize,
    /// Rows' worth of weight taken away by [`QrAccumulator::forget`]: the effective number of
    /// equations is `rows - forgotten` (0 without forgetting, and in states saved before it).
    #[serde(default)]
    forgotten: f64,
}

impl QrAccumulator {
    pub fn new(cols: usize) -> QrAccumulator {
        QrAccumulator {
            cols,
            r_rows: 0,
            r: Vec::new(),
            qtb: Vec::new(),
            rss_outside: 0.0,
            rows: 0,
            forgotten: 0.0,
        }
    }

    /// Weights every equation so far by `factor` (0 < factor <= 1) against those added later:
    /// exponential forgetting, so that the solution follows parameters that drift. R and Q^T b
    /// scale by sqrt(factor), the residual outside the factor by factor.
    pub fn forget(&mut self, factor: f64) {
        debug_assert!(factor > 0.0 && factor <= 1.0, "forgetting factor {factor}");
        let root = factor.sqrt();
        self.r.iter_mut().for_each(|v| *v *= root);
        self.qtb.iter_mut().for_each(|v| *v *= root);
        self.rss_outside *= factor;
        self.forgotten += (1.0 - factor) * self.effective_rows();
    }

    /// The equations' total weight (the row count without forgetting).
    pub fn effective_rows(&self) -> f64 {
        self.rows as f64 - self.forgotten
    }

    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Real equations added so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Adds the rows `a theta = b` (updates the factor by a Householder QR of [R; a]).
    pub fn add_rows(&mut self, a: &DMatrix<f64>, b: &DVector<f64>) -> Result<(), LstsqError> {
        let (m, cols) = a.shape();
        assert_eq!(cols, self.cols, "one column per parameter");
        assert_eq!(m, b.len(), "one right-hand side per row");
        if let Some(row) =
            (0..m).find(|&r| !b[r].is_finite() || a.row(r).iter().any(|v| !v.is_finite()))
        {
            return Err(LstsqError::NonFinite {
                row: self.rows + row,
            });
        }
        if m == 0 {
            return Ok(());
        }
        let total = self.r_rows + m;
        let mut stacked = DMatrix::zeros(total, cols);
        let mut c = DVector::zeros(total);
        for i in 0..self.r_rows {
            for j in 0..cols {
                stacked[(i, j)] = self.r[i * cols + j];
            }
            c[i] = self.qtb[i];
        }
        stacked.rows_mut(self.r_rows, m).copy_from(a);
        c.rows_mut(self.r_rows, m).copy_from(b);
        let qr = stacked.qr();
        qr.q_tr_mul(&mut c);
        let r = qr.r();
        let r_rows = total.min(cols);
        self.r = (0..r_rows)
            .flat_map(|i| (0..cols).map(move |j| (i, j)))
            .map(|(i, j)| r[(i, j)])
            .collect();
        self.qtb = c.rows(0, r_rows).iter().copied().collect();
        self.rss_outside += c.rows(r_rows, total - r_rows).norm_squared();
        self.r_rows = r_rows;
        self.rows += m;
        Ok(())
    }

    /// Adds the equations `other` holds, as its factor's rows [R | Q^T b] plus the residual
    /// outside them: the least squares of both sets of rows, equal to adding `other`'s rows
    /// here to rounding. Factors of blocks merged this way serve leave-one-block-out fits
    /// without factoring every other block's rows again for each.
    pub fn merge(&mut self, other: &QrAccumulator) -> Result<(), LstsqError> {
        assert_eq!(other.cols, self.cols, "one column per parameter");
        let a = DMatrix::from_row_slice(other.r_rows, other.cols, &other.r);
        let b = DVector::from_column_slice(&other.qtb);
        let rows = self.rows;
        self.add_rows(&a, &b)?;
        self.rows = rows + other.rows;
        self.rss_outside += other.rss_outside;
        self.forgotten += other.forgotten;
        Ok(())
    }

    /// Norm of each column of the equations so far (that of A, since Q is orthogonal).
    pub fn column_norms(&self) -> Vec<f64> {
        (0..self.cols)
            .map(|j| {
                (0..self.r_rows)
                    .map(|i| self.r[i * self.cols + j].powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect()
    }

    /// The least-squares solution of the rows so far, by SVD of the column-scaled R.
    pub fn solve(&self, names: &[String], variance_scale: f64) -> Result<Solution, LstsqError> {
        let (rows, cols) = (self.rows, self.cols);
        assert_eq!(cols, names.len(), "one name per column");
        if rows < cols {
            return Err(LstsqError::Underdetermined {
                equations: rows,
                parameters: cols,
                names: names.join(", "),
            });
        }
        let r = DMatrix::from_row_slice(self.r_rows, cols, &self.r);
        let qtb = DVector::from_column_slice(&self.qtb);
        // Scale columns to unit norm so that k [N/m] and s [N/m^3] are comparable.
        let norms = self.column_norms();
        let scale: Vec<f64> = norms
            .iter()
            .map(|&n| if n > 0.0 { n } else { 1.0 })
            .collect();
        let mut scaled = r.clone();
        for (j, s) in scale.iter().enumerate() {
            scaled.column_mut(j).unscale_mut(*s);
        }
        let svd = scaled.svd(true, true);
        let sv = &svd.singular_values;
        let s_max = sv.max();
        let s_min = sv.min();
        let condition = if s_min > 0.0 {
            s_max / s_min
        } else {
            f64::INFINITY
        };
        if condition > MAX_CONDITION_NUMBER || norms.contains(&0.0) {
            return Err(LstsqError::IllConditioned {
                condition,
                limit: MAX_CONDITION_NUMBER,
                names: unidentifiable(&svd.v_t.clone().expect("v_t requested"), sv, names, s_max),
            });
        }
        let u = svd.u.as_ref().expect("u requested");
        let v_t = svd.v_t.as_ref().expect("v_t requested");
        // theta_scaled = V diag(1/s) U^T Q^T b
        let utb = u.transpose() * &qtb;
        let mut y = DVector::zeros(cols);
        for i in 0..cols {
            y[i] = utb[i] / sv[i];
        }
        let theta_scaled = v_t.transpose() * y;
        let theta: Vec<f64> = (0..cols).map(|j| theta_scaled[j] / scale[j]).collect();

        let rss =
            self.rss_outside + (&r * DVector::from_column_slice(&theta) - &qtb).norm_squared();
        let dof = (self.effective_rows() - cols as f64).max(1.0);
        let s2 = rss / dof * variance_scale;
        // (A^T A)^-1 = D^-1 V diag(1/s^2) V^T D^-1
        let mut cov = DMatrix::zeros(cols, cols);
        for i in 0..cols {
            for j in 0..cols {
                let mut acc = 0.0;
                for m in 0..cols {
                    acc += v_t[(m, i)] * v_t[(m, j)] / (sv[m] * sv[m]);
                }
                cov[(i, j)] = s2 * acc / (scale[i] * scale[j]);
            }
        }
        let mut warnings = Vec::new();
        if condition > WARN_CONDITION_NUMBER {
            warnings.push(format!(
                "badly conditioned: condition number {condition:.3e}; weakly determined: {}",
                unidentifiable(v_t, sv, names, s_max)
            ));
        }
        Ok(Solution {
            theta,
            covariance: cov,
            condition_number: condition,
            equations: rows,
            residual_rms: (rss / self.effective_rows()).sqrt(),
            warnings,
        })
    }
}

/// Names the parameters that dominate the weakest singular directions.
fn unidentifiable(v_t: &DMatrix<f64>, sv: &DVector<f64>, names: &[String], s_max: f64) -> String {
    let mut out: Vec<String> = Vec::new();
    for (m, s) in sv.iter().enumerate() {
        if *s <= s_max / WARN_CONDITION_NUMBER || *s == 0.0 {
            // the parameters that take part in this (near) null direction
            let biggest = (0..names.len()).fold(0.0f64, |b, j| b.max(v_t[(m, j)].abs()));
            for (j, name) in names.iter().enumerate() {
                if v_t[(m, j)].abs() > 0.1 * biggest && !out.contains(name) {
                    out.push(name.clone());
                }
            }
        }
    }
    if out.is_empty() {
        // Fall back on the weakest direction.
        let m = sv.imin();
        let j = (0..names.len())
            .max_by(|&x, &y| v_t[(m, x)].abs().total_cmp(&v_t[(m, y)].abs()))
            .unwrap_or(0);
        out.push(names[j].clone());
    }
    out.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(ToString::to_string).collect()
    }

    #[test]
    fn consistent_system_is_solved_exactly_whatever_the_units() {
        // Columns of wildly different scale, as k x and s x^3 are.
        let x: Vec<f64> = (0..20).map(|i| 0.001 * (i as f64 + 1.0)).collect();
        let a = DMatrix::from_fn(20, 3, |r, c| match c {
            0 => x[r],
            1 => x[r].powi(3),
            _ => (r as f64 * 0.7).sin(),
        });
        let truth = [8000.0, 3e8, 5.0];
        let b = &a * DVector::from_column_slice(&truth);
        let s = solve(&a, &b, &names(&["k", "s", "fd"]), 1.0).unwrap();
        for (got, want) in s.theta.iter().zip(truth) {
            assert!((got / want - 1.0).abs() < 1e-9, "{got} vs {want}");
        }
        assert!(s.residual_rms < 1e-9);
        assert!(s.std().iter().all(|v| *v < 1e-6 * 3e8));
    }

    #[test]
    fn covariance_matches_monte_carlo_for_noisy_rows() {
        // y = 2 + 3 t + noise; OLS std of the slope is sigma / sqrt(sum (t - mean)^2).
        let n = 200;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
        let a = DMatrix::from_fn(n, 2, |r, c| if c == 0 { 1.0 } else { t[r] });
        let sigma = 0.1;
        // deterministic pseudo-noise with zero mean and known variance
        let noise: Vec<f64> = (0..n)
            .map(|i| sigma * 3f64.sqrt() * (2.0 * ((i * 7919 % 1000) as f64 / 1000.0) - 1.0))
            .collect();
        let b = DVector::from_fn(n, |r, _| 2.0 + 3.0 * t[r] + noise[r]);
        let s = solve(&a, &b, &names(&["a", "b"]), 1.0).unwrap();
        let mean = t.iter().sum::<f64>() / n as f64;
        let sxx: f64 = t.iter().map(|v| (v - mean).powi(2)).sum();
        let expect = sigma / sxx.sqrt();
        assert!(
            (s.std()[1] / expect - 1.0).abs() < 0.15,
            "{} vs {}",
            s.std()[1],
            expect
        );
    }

    #[test]
    fn refuses_and_names_what_cannot_be_identified() {
        let a = DMatrix::from_fn(10, 3, |r, c| match c {
            0 => r as f64,
            1 => 2.0 * r as f64, // collinear with column 0
            _ => 1.0,
        });
        let b = DVector::from_element(10, 1.0);
        let e = solve(&a, &b, &names(&["k", "k2", "offset"]), 1.0).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("k, k2") && !msg.contains("offset"), "{msg}");
        let e = solve(
            &DMatrix::zeros(1, 2),
            &DVector::zeros(1),
            &names(&["k", "c"]),
            1.0,
        )
        .unwrap_err();
        assert!(matches!(
            e,
            LstsqError::Underdetermined {
                equations: 1,
                parameters: 2,
                ..
            }
        ));
        let mut a = DMatrix::identity(3, 2);
        a[(2, 1)] = f64::NAN;
        let e = solve(&a, &DVector::zeros(3), &names(&["k", "c"]), 1.0).unwrap_err();
        assert_eq!(e, LstsqError::NonFinite { row: 2 });
    }

    /// Rows added in blocks (some shorter than the parameter count) give what the normal
    /// equations of all rows at once give, and the residual of the whole system.
    #[test]
    fn blocks_accumulate_to_the_solution_of_all_rows() {
        let n = 40;
        let a = DMatrix::from_fn(n, 3, |r, c| {
            let x = r as f64 * 0.37;
            match c {
                0 => x.sin() * 1e3,
                1 => x.cos(),
                _ => (x * 0.5).sin() * 1e-4,
            }
        });
        let truth = [2.0, -3.0, 5e4];
        let b = DVector::from_fn(n, |r, _| {
            (0..3).map(|c| a[(r, c)] * truth[c]).sum::<f64>() + 0.01 * ((r * 7 % 11) as f64 - 5.0)
        });
        let mut acc = QrAccumulator::new(3);
        let mut r0 = 0;
        for len in [1, 2, 5, 13, 19] {
            acc.add_rows(&a.rows(r0, len).into_owned(), &b.rows(r0, len).into_owned())
                .unwrap();
            r0 += len;
        }
        assert_eq!(r0, n);
        let names = names(&["k", "c", "s"]);
        let got = acc.solve(&names, 1.0).unwrap();
        // independent check: normal equations in full
        let ata = a.transpose() * &a;
        let atb = a.transpose() * &b;
        let direct = ata.clone().lu().solve(&atb).unwrap();
        for j in 0..3 {
            assert!(((got.theta[j] - direct[j]) / direct[j]).abs() < 1e-9, "{j}");
        }
        let res = &a * DVector::from_column_slice(&got.theta) - &b;
        assert!((got.residual_rms - (res.norm_squared() / n as f64).sqrt()).abs() < 1e-12);
        assert_eq!(got.equations, n);
        // the column norms are those of A
        for (j, nrm) in acc.column_norms().iter().enumerate() {
            assert!((nrm / a.column(j).norm() - 1.0).abs() < 1e-12);
        }
    }

    /// Blocks factored apart and merged give the fit of all their rows: theta, residual,
    /// standard deviations and equation count; a block left out gives the fit of the others.
    #[test]
    fn merged_blocks_are_the_fit_of_their_rows() {
        let n = 60;
        let a = DMatrix::from_fn(n, 3, |r, c| {
            let x = r as f64 * 0.29;
            match c {
                0 => x.sin() * 1e3,
                1 => x.cos(),
                _ => (x * 0.7).cos() * 1e-4,
            }
        });
        let b = DVector::from_fn(n, |r, _| {
            2.0 * a[(r, 0)] - 3.0 * a[(r, 1)] + 5e4 * a[(r, 2)] + 0.01 * ((r * 5 % 13) as f64 - 6.0)
        });
        let names = names(&["k", "c", "s"]);
        // Blocks of 2 rows (fewer than the columns), 18 and 40.
        let bounds = [(0, 2), (2, 18), (20, 40)];
        let block = |&(r0, len): &(usize, usize)| {
            let mut acc = QrAccumulator::new(3);
            acc.add_rows(&a.rows(r0, len).into_owned(), &b.rows(r0, len).into_owned())
                .unwrap();
            acc
        };
        let blocks: Vec<QrAccumulator> = bounds.iter().map(block).collect();
        let close = |got: &Solution, want: &Solution| {
            assert_eq!(got.equations, want.equations);
            for j in 0..3 {
                assert!(
                    (got.theta[j] / want.theta[j] - 1.0).abs() < 1e-10,
                    "theta {j}"
                );
                assert!((got.std()[j] / want.std()[j] - 1.0).abs() < 1e-8, "std {j}");
            }
            assert!((got.residual_rms / want.residual_rms - 1.0).abs() < 1e-8);
        };
        let mut all = QrAccumulator::new(3);
        blocks.iter().for_each(|blk| all.merge(blk).unwrap());
        let mut direct = QrAccumulator::new(3);
        direct.add_rows(&a, &b).unwrap();
        close(
            &all.solve(&names, 1.0).unwrap(),
            &direct.solve(&names, 1.0).unwrap(),
        );
        // Without the middle block: the fit of the first and last blocks' rows.
        let mut out = QrAccumulator::new(3);
        out.merge(&blocks[0]).unwrap();
        out.merge(&blocks[2]).unwrap();
        let mut rows = QrAccumulator::new(3);
        for k in [0, 2] {
            let (r0, len) = bounds[k];
            rows.add_rows(&a.rows(r0, len).into_owned(), &b.rows(r0, len).into_owned())
                .unwrap();
        }
        close(
            &out.solve(&names, 1.0).unwrap(),
            &rows.solve(&names, 1.0).unwrap(),
        );
    }

    /// The state survives a JSON round trip bit for bit (the identifier persists it).
    #[test]
    fn accumulated_state_round_trips_exactly_through_json() {
        let a = DMatrix::from_fn(7, 2, |r, c| {
            ((r + 1) as f64).powi(c as i32 + 1).sqrt() / 3.0
        });
        let b = DVector::from_fn(7, |r, _| (r as f64 * 1.7).sin());
        let mut acc = QrAccumulator::new(2);
        acc.add_rows(&a, &b).unwrap();
        let text = serde_json::to_string(&acc).unwrap();
        let back: QrAccumulator = serde_json::from_str(&text).unwrap();
        assert_eq!(back, acc);
        let names = names(&["k", "c"]);
        assert_eq!(
            back.solve(&names, 1.0).unwrap().theta,
            acc.solve(&names, 1.0).unwrap().theta
        );
    }

    #[test]
    fn forgetting_weighs_the_earlier_rows_by_the_factor() {
        let names = vec!["a".to_string(), "b".to_string()];
        let a1 = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 1.0, 1.0, 0.0, 2.0]);
        let b1 = DVector::from_column_slice(&[1.0, 2.5, 3.0]);
        let a2 = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, -1.0]);
        let b2 = DVector::from_column_slice(&[4.0, 0.2]);
        let factor: f64 = 0.6;
        let mut acc = QrAccumulator::new(2);
        acc.add_rows(&a1, &b1).unwrap();
        acc.forget(factor);
        acc.add_rows(&a2, &b2).unwrap();
        let got = acc.solve(&names, 1.0).unwrap();
        // The same least squares with the first rows scaled by sqrt(factor).
        let mut a = DMatrix::zeros(5, 2);
        let mut b = DVector::zeros(5);
        a.rows_mut(0, 3).copy_from(&(a1 * factor.sqrt()));
        b.rows_mut(0, 3).copy_from(&(b1 * factor.sqrt()));
        a.rows_mut(3, 2).copy_from(&a2);
        b.rows_mut(3, 2).copy_from(&b2);
        let want = solve(&a, &b, &names, 1.0).unwrap();
        for (g, w) in got.theta.iter().zip(&want.theta) {
            assert!((g - w).abs() < 1e-12, "{g} vs {w}");
        }
        // 2 rows plus 3 weighed 0.6: 3.8 rows' weight.
        assert!((acc.effective_rows() - 3.8).abs() < 1e-12);
    }
}
