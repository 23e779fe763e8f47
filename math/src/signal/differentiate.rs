//! Central differences of sampled signals, one-sided at the ends.
//!
//! Two roundings of the same derivative exist because each user's results were computed with
//! one of them: they differ in the last bits only, which would still change the EMPS figures
//! or the rig diagnosis if one replaced the other.

/// Central differences, one-sided at the ends, dividing by the step: `(x[i+1] - x[i-1]) /
/// (2 dt)`. Fewer than two samples give zeros. The time-domain path's (the EMPS
/// identification script's `diffcent`).
pub fn central_difference(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return vec![0.0; n];
    }
    (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(1), (i + 1).min(n - 1));
            (x[hi] - x[lo]) / ((hi - lo) as f64 * dt)
        })
        .collect()
}

/// Central differences, one-sided at the ends, multiplying by the rate: `(x[i+1] - x[i-1]) *
/// fs / 2`. One sample gives zero. The rig diagnosis's scoring (`diagnose::score`: undoing a
/// sensor low-pass on the base input).
pub fn central_difference_at_rate(x: &[f64], sample_rate_hz: f64) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|i| {
            let lo = i.saturating_sub(1);
            let hi = (i + 1).min(n - 1);
            (x[hi] - x[lo]) * sample_rate_hz / (hi - lo).max(1) as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_roundings_differentiate_a_parabola_exactly_inside_and_one_sided_at_the_ends() {
        let x: Vec<f64> = (0..6).map(|i| (i * i) as f64).collect();
        for d in [
            central_difference(&x, 0.5),
            central_difference_at_rate(&x, 2.0),
        ] {
            assert_eq!(d, vec![2.0, 4.0, 8.0, 12.0, 16.0, 18.0]);
        }
        assert_eq!(central_difference(&[1.0], 0.1), vec![0.0]);
        assert_eq!(central_difference_at_rate(&[1.0], 10.0), vec![0.0]);
    }
}
