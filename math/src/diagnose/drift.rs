//! The drift candidate: the baseline's damping changes over the run (thermal fade),
//! `c(t) = c0 (1 + r t)` with t the time since the start of the run. Linear in `c0` and
//! `c0 r`: each step's equations carry the step's own time (the middle of its averaged
//! periods, [`super::cycles::StepCycle::time_s`]), and a held-out record is replayed with the
//! damping of its time ([`super::fit::Fitted::element_at`]). The rate is reported per minute
//! and per kJ the element dissipated, the run's dissipation measured from the records.

use super::fit::Fitted;
use super::series::DAMPER_SYMBOL;
use crate::record::{Channel, Record};
use crate::signal::differentiate::central_difference_at_rate;

/// The symbol of the drift's coefficient `c0 r` [N s/m per s].
pub const RATE_SYMBOL: &str = "c_rate";

/// What the element dissipated over a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunDissipation {
    /// Energy the element dissipated over the records [J].
    pub energy_j: f64,
    /// From the start of the first record to the end of the last [s].
    pub duration_s: f64,
}

/// The element's dissipation over the rig's records: the integral of the element force
/// `g = -m x_o''` times the relative velocity (central differences of the relative
/// displacement). None without records holding both channels.
pub fn run_dissipation(records: &[Record], mass_kg: f64) -> Option<RunDissipation> {
    let mut energy_j = 0.0;
    let (mut start, mut end) = (f64::INFINITY, f64::NEG_INFINITY);
    for r in records {
        let (Some(a), Some(x)) = (
            r.channel(Channel::MassAccelerationMps2),
            r.channel(Channel::RelativeDisplacementM),
        ) else {
            continue;
        };
        let fs = r.sample_rate_hz;
        let v = central_difference_at_rate(x, fs);
        energy_j += a.iter().zip(&v).map(|(a, v)| -mass_kg * a * v).sum::<f64>() / fs;
        start = start.min(r.start_time_s);
        end = end.max(r.start_time_s + r.len() as f64 / fs);
    }
    (end > start).then_some(RunDissipation {
        energy_j,
        duration_s: end - start,
    })
}

/// (c0 [N s/m], r [1/s]) of a drift fit.
pub fn rate(f: &Fitted) -> Option<(f64, f64)> {
    if !f.structure.drift {
        return None;
    }
    let c0 = f.coefficient(DAMPER_SYMBOL)?;
    let rate = f.coefficient(RATE_SYMBOL)?;
    Some((c0, rate / c0))
}

/// The fitted drift, e.g. "damping -12.0 %/min, -3.4 %/kJ, c 184.0 N s/m at the start of the
/// run"; the
/// rate per kJ with the run's mean dissipation rate, when known.
pub fn describe(f: &Fitted, run: Option<&RunDissipation>) -> Option<String> {
    let (c0, r) = rate(f)?;
    let per_min = 100.0 * 60.0 * r;
    let per_kj = run
        .filter(|d| d.energy_j > 0.0 && d.duration_s > 0.0)
        .map(|d| {
            format!(
                ", {:+.1} %/kJ",
                100.0 * r * d.duration_s / (d.energy_j / 1e3)
            )
        })
        .unwrap_or_default();
    Some(format!(
        "damping {per_min:+.1} %/min{per_kj}, c {c0:.1} N s/m at the start of the run"
    ))
}
