//! The covariance of an output-error fit from its residuals as they are, for residuals that
//! are not white (noise on a measured input that drives the simulation, a smooth form error).

use std::ops::Range;

use nalgebra::DMatrix;

use super::lm::{self, Problem};
use crate::identify::IdentifyError;

/// The covariance of the parameters from the residuals as they are: the sandwich
/// `B^-1 M B^-1` with `B = J^T J` and `M` the Bartlett-weighted sum of the products of the
/// per-sample scores `J_i r_i` up to the lag where the residual stops being correlated,
/// within each block of `blocks` (a record's channel: contiguous residual rows). The residual
/// is not white (the noise on the measured input drives the simulated mass, and a form error
/// is smooth), and the Gauss-Newton covariance would then understate the uncertainty several
/// times over.
pub(crate) fn sandwich_covariance(
    problem: &impl Problem,
    fit: &lm::Fit,
    blocks: &[Range<usize>],
) -> Result<DMatrix<f64>, IdentifyError> {
    let np = fit.p.len();
    let jac = lm::jacobian(problem, &fit.p, &fit.residual, &fit.scale)?;
    let r = &fit.residual;
    let lag = correlation_lag(blocks, r);
    let mut meat = DMatrix::<f64>::zeros(np, np);
    // Flat rows and sums, no matrix per sample, and only the parameters that move the block's
    // rows (another record's initial state adds exact zeros): the same products, added in the
    // same order.
    let mut scores: Vec<f64> = Vec::new();
    let mut sum: Vec<f64> = Vec::new();
    for block in blocks {
        let active: Vec<usize> = (0..np)
            .filter(|&j| block.clone().any(|i| jac[(i, j)] != 0.0))
            .collect();
        let k = active.len();
        scores.clear();
        for i in block.clone() {
            scores.extend(active.iter().map(|&j| jac[(i, j)] * r[i]));
        }
        let n = block.len();
        for l in 0..=lag.min(n.saturating_sub(1)) {
            let w = if l == 0 {
                1.0
            } else {
                1.0 - l as f64 / (lag + 1) as f64
            };
            sum.clear();
            sum.resize(k * k, 0.0);
            for i in 0..n - l {
                let (now, later) = (&scores[i * k..][..k], &scores[(i + l) * k..][..k]);
                for (a, sa) in now.iter().enumerate() {
                    let row = &mut sum[a * k..][..k];
                    for (acc, sb) in row.iter_mut().zip(later) {
                        *acc += sa * sb;
                    }
                }
            }
            for (a, &ja) in active.iter().enumerate() {
                for (b, &jb) in active.iter().enumerate() {
                    meat[(ja, jb)] += if l == 0 {
                        sum[a * k + b] * w
                    } else {
                        (sum[a * k + b] + sum[b * k + a]) * w
                    };
                }
            }
        }
    }
    let bread = (jac.transpose() * &jac)
        .try_inverse()
        .unwrap_or_else(|| DMatrix::from_element(np, np, f64::NAN));
    let cov = &bread * meat * &bread;
    Ok(DMatrix::from_fn(np, np, |i, j| {
        cov[(i, j)] * fit.scale[i] * fit.scale[j]
    }))
}

/// The lag beyond which the residual is uncorrelated (pooled over the records): the
/// last lag whose autocorrelation's magnitude reaches its white-noise band `2 / sqrt(N)`,
/// looked for until the autocorrelation has stayed inside the band for as many lags again
/// (a residual driven through a resonance oscillates: its autocorrelation crosses zero at a
/// quarter period and comes back, and stopping at the first crossing understates the
/// variance); at most a tenth of the shortest record.
fn correlation_lag(blocks: &[Range<usize>], r: &[f64]) -> usize {
    let shortest = blocks.iter().map(ExactSizeIterator::len).min().unwrap_or(0);
    let variance: f64 = r.iter().map(|v| v * v).sum();
    if variance <= 0.0 || shortest < 20 {
        return 0;
    }
    let band = 2.0 / (r.len() as f64).sqrt();
    let cap = shortest / 10;
    let mut last_correlated = 0;
    for l in 1..cap {
        if l > 2 * last_correlated.max(1) {
            break;
        }
        let c: f64 = blocks
            .iter()
            .map(|b| (b.start..b.end - l).map(|i| r[i] * r[i + l]).sum::<f64>())
            .sum();
        if (c / variance).abs() >= band {
            last_correlated = l;
        }
    }
    (last_correlated + 1).min(cap)
}
