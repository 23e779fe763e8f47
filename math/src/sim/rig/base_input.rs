//! The rig's true base motion at the integrator's times: the piece of the piecewise base
//! signal, its Taylor windows and spline intervals, and the values remembered between RK4
//! stages (most of an evaluation would otherwise be the search and the window).

use super::RigSystem;
use crate::sim::excitation::{CubicSpline, Derivs, Piece};
use crate::sim::input_window::{InputWindow, SplineInterval};

impl RigSystem<'_> {
    pub(super) fn base_true_at(&self, t: f64, t_ref: f64) -> Derivs {
        self.base_true.eval(t, t_ref)
    }

    /// Index of the piece of the true base at `t_ref` (the last one remembered: the search
    /// is most of an evaluation otherwise).
    pub(super) fn base_true_index(&self, t_ref: f64) -> usize {
        let sig = &self.base_true;
        // The comparisons of `PiecewiseSignal::index`, in the signal's own time.
        let tr = t_ref - sig.shift;
        let (lo, hi, j) = self.piece.get();
        if lo <= tr && tr < hi {
            return j;
        }
        let j = sig.index(t_ref);
        let end = sig.starts.get(j + 1).copied().unwrap_or(f64::INFINITY);
        self.piece.set((sig.starts[j], end, j));
        j
    }

    /// The true base acceleration (`order` 2) or displacement (0) at `t` (piece of `t_ref`),
    /// without a `sin_cos` per component where the piece is sine-like.
    pub(super) fn base_true_window(&self, order: u32, t: f64, t_ref: f64) -> f64 {
        let sig = &self.base_true;
        let j = self.base_true_index(t_ref);
        let piece = &sig.pieces[j];
        let tl = t - sig.shift;
        // A spline piece has no Taylor window, and only windows fill `last_d2` and
        // `last_value`: straight to the spline.
        if let Piece::Spline(s) = piece {
            if order != 2 {
                return piece.eval(tl, t_ref - sig.shift).value;
            }
            if let Some((lj, lt, lr, v)) = self.last_spline_d2.get()
                && (lj, lt, lr) == (j, t, t_ref)
            {
                return v;
            }
            let v = self.spline_d2(j, s, tl, t_ref - sig.shift);
            self.last_spline_d2.set(Some((j, t, t_ref, v)));
            return v;
        }
        let slot = usize::from(order == 0);
        let last = if order == 2 {
            &self.last_d2
        } else {
            &self.last_value
        };
        if let Some((lj, lt, v)) = last.get()
            && lj == j
            && lt == t
        {
            return v;
        }
        if let Some(v) =
            InputWindow::eval(&mut self.windows.borrow_mut()[slot], order, j, piece, tl)
        {
            last.set(Some((j, t, v)));
            return v;
        }
        let d = piece.eval(tl, t_ref - sig.shift);
        if order == 0 { d.value } else { d.d2 }
    }

    /// The second derivative of spline piece `j` at `t` ([`SplineInterval`]), its interval
    /// remembered for `tr`.
    #[inline(always)]
    pub(super) fn spline_d2(&self, j: usize, s: &CubicSpline, t: f64, tr: f64) -> f64 {
        let interval = match self.spline_interval.get() {
            Some((lj, lr, iv)) if (lj, lr) == (j, tr) => iv,
            _ => {
                let iv = SplineInterval::of(s, tr);
                self.spline_interval.set(Some((j, tr, iv)));
                iv
            }
        };
        interval.map_or(0.0, |iv| iv.d2(t))
    }

    /// The true base acceleration at `t` (piece of `t_ref`). The values remembered are
    /// looked up here, inlined: three of an RK4 step's four stages find theirs there, and the
    /// call of `base_true_window` cost more than the lookup.
    #[inline(always)]
    pub(super) fn base_true_d2(&self, t: f64, t_ref: f64) -> f64 {
        let j = self.base_true_index(t_ref);
        if let Some((lj, lt, v)) = self.last_d2.get()
            && lj == j
            && lt == t
        {
            return v;
        }
        if let Some((aj, at, ar, v)) = self.ahead.get()
            && (aj, at, ar) == (j, t, t_ref)
        {
            // Remembered where `base_true_window` would have put it.
            self.ahead.set(None);
            match self.base_true.pieces[j] {
                Piece::Spline(_) => self.last_spline_d2.set(Some((j, t, t_ref, v))),
                _ => self.last_d2.set(Some((j, t, v))),
            }
            return v;
        }
        if let Some((lj, lt, lr, v)) = self.last_spline_d2.get()
            && (lj, lt, lr) == (j, t, t_ref)
        {
            return v;
        }
        self.base_true_window(2, t, t_ref)
    }

    /// [`RigSystem::base_true_d2`] at two times.
    #[inline(always)]
    pub(super) fn base_true_d2_pair(&self, t: [f64; 2], t_ref: f64) -> [f64; 2] {
        let sig = &self.base_true;
        let j = self.base_true_index(t_ref);
        let piece = &sig.pieces[j];
        let tl = [t[0] - sig.shift, t[1] - sig.shift];
        let mut windows = self.windows.borrow_mut();
        let [w_d2, w_value] = &mut *windows;
        // The nearest sample index (`+ 0.5` and truncation: `round` is a libm call on x86-64,
        // and a time that is no sample time comes out false either way).
        // (`as i64`: one instruction where `as u64` is a dozen; the time is not negative.)
        let i = (t[1] * self.sample_rate_hz + 0.5) as i64 as f64;
        let at_sample = i / self.sample_rate_hz == t[1];
        let also = at_sample.then_some((&*w_value, 0, tl[1]));
        if let Some((v, value)) = InputWindow::eval_pair_with(w_d2, 2, j, piece, tl, also) {
            self.last_d2.set(Some((j, t[1], v[1])));
            if let Some(value) = value {
                self.last_value.set(Some((j, t[1], value)));
            }
            return v;
        }
        let tr = t_ref - sig.shift;
        match piece {
            Piece::Spline(s) => [
                self.spline_d2(j, s, tl[0], tr),
                self.spline_d2(j, s, tl[1], tr),
            ],
            _ => [piece.eval(tl[0], tr).d2, piece.eval(tl[1], tr).d2],
        }
    }
}
