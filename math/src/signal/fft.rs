//! FFT plans of the thread, remembered by length: a plan computes its twiddle factors when it
//! is built, which costs more than transforming one period of a few hundred points, and the
//! diagnosis transforms thousands of such periods. Plans longer than
//! [`REMEMBERED_MAX_LEN`] (a whole record's transform) are built afresh each time, so that their
//! twiddles are not kept for the life of the thread.

use std::cell::RefCell;
use std::sync::Arc;

use rustfft::{Fft, FftPlanner};

/// The longest plan remembered (1 MiB of twiddle factors).
pub const REMEMBERED_MAX_LEN: usize = 1 << 16;

thread_local! {
    static PLANNER: RefCell<FftPlanner<f64>> = RefCell::new(FftPlanner::new());
}

/// The forward FFT of length `len` (the same plan a fresh `FftPlanner` builds, so the same
/// numbers).
pub fn forward(len: usize) -> Arc<dyn Fft<f64>> {
    if len > REMEMBERED_MAX_LEN {
        return FftPlanner::new().plan_fft_forward(len);
    }
    PLANNER.with(|p| p.borrow_mut().plan_fft_forward(len))
}

/// The inverse (unnormalised) FFT of length `len`.
pub fn inverse(len: usize) -> Arc<dyn Fft<f64>> {
    if len > REMEMBERED_MAX_LEN {
        return FftPlanner::new().plan_fft_inverse(len);
    }
    PLANNER.with(|p| p.borrow_mut().plan_fft_inverse(len))
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    #[test]
    fn remembered_plans_transform_as_fresh_ones_do() {
        for len in [7, 64, 256, 1000, REMEMBERED_MAX_LEN + 2] {
            let x: Vec<Complex64> = (0..len)
                .map(|i| Complex64::new((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos()))
                .collect();
            let (mut a, mut b) = (x.clone(), x.clone());
            forward(len).process(&mut a);
            FftPlanner::new().plan_fft_forward(len).process(&mut b);
            assert_eq!(a, b, "forward {len}");
            let remembered = Arc::ptr_eq(&forward(len), &forward(len));
            assert_eq!(remembered, len <= REMEMBERED_MAX_LEN, "{len}");
            let (mut a, mut b) = (x.clone(), x);
            inverse(len).process(&mut a);
            FftPlanner::new().plan_fft_inverse(len).process(&mut b);
            assert_eq!(a, b, "inverse {len}");
        }
    }
}
