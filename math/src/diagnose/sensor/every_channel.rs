//! The sensor member on every channel refined on the sine steps. A filter on every channel
//! leaves the channel identities intact ([`super::identities`] cannot see it), so its member is
//! chosen by the element fit's cross-validated force error on the steps, on a grid of cutoffs
//! (`effects::LOWPASS_CUTOFF_MULTIPLES`, second order at `LOWPASS_SECOND_ORDER_MULTIPLES` with
//! zeta 0.7). Once the held-out records undo the filter right, what a grid member leaves of the
//! planted one (the cutoff off by a grid step, zeta 0.7 against 0.56) shows there as a lag that
//! a series spring takes up; the member is refined continuously from the grid's best here.

use super::identities::{CUTOFF_BOUNDS, DAMPING_BOUNDS, nelder_mead};
use super::{ALL_CHANNELS, SensorFilter};
use crate::diagnose::effects::{Structure, sensor_structure};
use crate::diagnose::search::PhasorCandidate;

/// Fits (with their cross-validation) a refinement may take: a simplex in one or two
/// dimensions from a grid point a step from the optimum.
pub const EVERY_CHANNEL_REFINE_EVALUATIONS: usize = 30;

/// The best grid member on every channel refined by a Nelder-Mead simplex over ln cutoff (and
/// the damping ratio for order 2), within the single-channel members' bounds, minimising the
/// sine steps' choosing error ([`PhasorCandidate::step_error_percent`]): the criterion that
/// chose it on the grid (the held-out records score it and are not used). `evaluate` fits and
/// cross-validates one structure (None when its fit fails or is not physical). The member's
/// parameter count is unchanged (the grid's second-order member already counts its damping
/// ratio). Keeps the grid's candidate if nothing beats it; other candidates are returned as
/// they are.
pub fn refine_on_every_channel<E>(
    best: PhasorCandidate,
    max_frequency_hz: f64,
    mut evaluate: impl FnMut(Structure) -> Result<Option<PhasorCandidate>, E>,
) -> Result<PhasorCandidate, E> {
    let Some(start) = best.structure.transform.sensor else {
        return Ok(best);
    };
    if start.mask & ALL_CHANNELS != ALL_CHANNELS || max_frequency_hz <= 0.0 {
        return Ok(best);
    }
    let second = start.order == 2;
    let (lo, hi) = (
        (CUTOFF_BOUNDS[0] * max_frequency_hz).ln(),
        (CUTOFF_BOUNDS[1] * max_frequency_hz).ln(),
    );
    let build = |p: &[f64]| SensorFilter {
        cutoff_hz: p[0].clamp(lo, hi).exp(),
        damping_ratio: if second {
            p[1].clamp(DAMPING_BOUNDS[0], DAMPING_BOUNDS[1])
        } else {
            start.damping_ratio
        },
        ..start
    };
    let mut x0 = vec![start.cutoff_hz.ln()];
    let mut step = vec![0.2];
    if second {
        x0.push(start.damping_ratio);
        step.push(0.15);
    }
    let key = PhasorCandidate::step_error_percent;
    let mut winner = best;
    let mut failed = None;
    nelder_mead(
        |p| {
            if failed.is_some() {
                return f64::INFINITY;
            }
            match evaluate(sensor_structure(&build(p))) {
                Ok(Some(c)) => {
                    let k = key(&c);
                    if k < key(&winner) {
                        winner = c;
                    }
                    k
                }
                Ok(None) => f64::INFINITY,
                Err(e) => {
                    failed = Some(e);
                    f64::INFINITY
                }
            }
        },
        &x0,
        &step,
        EVERY_CHANNEL_REFINE_EVALUATIONS,
    );
    match failed {
        Some(e) => Err(e),
        None => Ok(winner),
    }
}
