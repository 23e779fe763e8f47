//! The stick intervals of a step's cycle and the polynomials that stand for the unknown
//! element force while it sticks (the improved method's stick-force columns, `fd`).

/// Runs of `false` in a circular mask, as (start, length); a mask that is all `false` is one
/// run starting at 0.
pub(super) fn circular_runs(keep: &[bool]) -> Vec<(usize, usize)> {
    let l = keep.len();
    let Some(first_kept) = keep.iter().position(|k| *k) else {
        return vec![(0, l)];
    };
    let mut runs = Vec::new();
    let mut i = 0;
    while i < l {
        let idx = (first_kept + i) % l;
        if keep[idx] {
            i += 1;
            continue;
        }
        let start = idx;
        let mut len = 0;
        while i < l && !keep[(first_kept + i) % l] {
            len += 1;
            i += 1;
        }
        runs.push((start, len));
    }
    runs
}

/// Legendre polynomials P_0..P_d at t in [-1, 1].
pub(super) fn legendre(t: f64, d: usize) -> Vec<f64> {
    let mut p = vec![1.0; d + 1];
    if d >= 1 {
        p[1] = t;
    }
    for k in 2..=d {
        p[k] = ((2 * k - 1) as f64 * t * p[k - 1] - (k - 1) as f64 * p[k - 2]) / k as f64;
    }
    p
}
