//! A sampled signal shifted in time by a fraction of a sample: the exciter delay a rig
//! candidate undoes, a sensor filter's delay, the scored prediction's.

/// Samples of `x` at times shifted by `-delay_s` (Catmull-Rom cubic interpolation, ends held).
pub fn delayed(x: &[f64], sample_rate_hz: f64, delay_s: f64) -> Vec<f64> {
    let n = x.len();
    let at = |i: isize| x[i.clamp(0, n as isize - 1) as usize];
    let shift = delay_s * sample_rate_hz;
    (0..n)
        .map(|i| {
            let t = i as f64 - shift;
            let i0 = t.floor() as isize;
            let u = t - i0 as f64;
            let (p0, p1, p2, p3) = (at(i0 - 1), at(i0), at(i0 + 1), at(i0 + 2));
            p1 + 0.5
                * u
                * (p2 - p0
                    + u * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + u * (3.0 * (p1 - p2) + p3 - p0)))
        })
        .collect()
}
