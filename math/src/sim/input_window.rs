//! A sine or multisine input (its value or second derivative) near a point, from a Taylor
//! polynomial.
//!
//! The integrators evaluate the base acceleration at every half sub-step; a multisine of 64
//! components costs 64 `sin_cos` per evaluation (two thirds of a paper rig run went there).
//! Around a centre c, `u(c + s) = sum_k u^(k)(c) s^k / k!` with the derivatives in closed
//! form (u the value, order 0, or the second derivative, order 2); the window half-width is
//! chosen so that the truncation bound `sum_j a_j w_j^(o+D+1) w^(D+1) / (D+1)!` stays below
//! 1e-16 of `sum_j a_j w_j^o` (a bound on |u|), i.e. below rounding, and a new window is
//! built when `t` leaves the current one.

use super::excitation::{CubicSpline, Piece};

/// Degree of the Taylor polynomial.
const DEGREE: usize = 12;
/// Truncation bound relative to the largest possible |u''|.
const RELATIVE_TRUNCATION: f64 = 1e-16;

/// A window of one piece of a signal (by its index), in the piece's own time.
#[derive(Debug, Clone)]
pub(crate) struct InputWindow {
    /// Derivative order of u (0: value, 2: second derivative).
    order: u32,
    piece: usize,
    centre_s: f64,
    half_width_s: f64,
    coeffs: [f64; DEGREE + 1],
}

/// (amplitude, angular frequency, phase at local time 0) of every component of a sine-like
/// piece; None for other pieces.
fn components(piece: &Piece) -> Option<Vec<(f64, f64, f64)>> {
    match piece {
        Piece::Sine {
            amplitude,
            omega,
            phase,
            ..
        } => Some(vec![(*amplitude, *omega, *phase)]),
        Piece::Multisine { signal, .. } => Some(
            signal
                .omegas
                .iter()
                .zip(&signal.phases)
                .map(|(&w, &p)| (signal.component_amplitude, w, p))
                .collect(),
        ),
        Piece::Const(_) | Piece::Spline(_) | Piece::Sweep { .. } => None,
    }
}

impl InputWindow {
    /// A window of `piece` (index `index`) starting at local time `tau`.
    fn build(order: u32, index: usize, comps: &[(f64, f64, f64)], tau: f64) -> InputWindow {
        let mut scale = 0.0;
        let mut high = 0.0;
        for &(a, w, _) in comps {
            scale += a.abs() * w.powi(order as i32);
            high += a.abs() * w.powi((order as usize + DEGREE + 1) as i32);
        }
        let factorial: f64 = (1..=DEGREE + 1).map(|k| k as f64).product();
        let half_width_s = if high > 0.0 {
            (RELATIVE_TRUNCATION * factorial * scale / high).powf(1.0 / (DEGREE as f64 + 1.0))
        } else {
            f64::INFINITY
        };
        // Time runs forward: centre the window so that it covers [tau, tau + 2 w].
        let centre_s = if half_width_s.is_finite() {
            tau + half_width_s
        } else {
            tau
        };
        let mut coeffs = [0.0; DEGREE + 1];
        for &(a, w, p) in comps {
            let (s, c) = (w * centre_s + p).sin_cos();
            // n-th derivative of a sin(theta): a w^n times S, C, -S, -C for n mod 4.
            let mut wk = a * w.powi(order as i32);
            let mut inv_fact = 1.0;
            for (k, ck) in coeffs.iter_mut().enumerate() {
                if k > 0 {
                    wk *= w;
                    inv_fact /= k as f64;
                }
                let trig = match (k + order as usize) % 4 {
                    0 => s,
                    1 => c,
                    2 => -s,
                    _ => -c,
                };
                *ck += wk * trig * inv_fact;
            }
        }
        InputWindow {
            order,
            piece: index,
            centre_s,
            half_width_s,
            coeffs,
        }
    }

    /// The `order`-th derivative (0 or 2) of `piece` (index `index`) at signal time `t`,
    /// through `window` (rebuilt when needed); None when the piece is not sine-like.
    pub fn eval(
        window: &mut Option<InputWindow>,
        order: u32,
        index: usize,
        piece: &Piece,
        t: f64,
    ) -> Option<f64> {
        Self::eval_pair(window, order, index, piece, [t, t]).map(|[a, _]| a)
    }

    /// [`InputWindow::eval`] at two times (the second later than the first), the two Horner
    /// chains interleaved (the integrators need the middle and the end of a sub-step).
    pub fn eval_pair(
        window: &mut Option<InputWindow>,
        order: u32,
        index: usize,
        piece: &Piece,
        t: [f64; 2],
    ) -> Option<[f64; 2]> {
        Self::eval_pair_with(window, order, index, piece, t, None).map(|(v, _)| v)
    }

    /// [`InputWindow::eval_pair`], and with it `also = (window, order, time)`: that window's
    /// value at that time when the window is of the same piece and covers the time already
    /// (it is never rebuilt here, so what it gives later is unchanged), in the same pass: the
    /// chains are independent, so the third costs little more than its operations. Each value
    /// is computed with the operations of [`InputWindow::eval`], to the bit. Inlined: at 10 kHz
    /// the rig calls it once per sample, and its results through memory were a tenth of it.
    #[inline(always)]
    pub fn eval_pair_with(
        window: &mut Option<InputWindow>,
        order: u32,
        index: usize,
        piece: &Piece,
        t: [f64; 2],
        also: Option<(&Option<InputWindow>, u32, f64)>,
    ) -> Option<([f64; 2], Option<f64>)> {
        let t0 = match piece {
            Piece::Sine { t0, .. } | Piece::Multisine { t0, .. } => *t0,
            Piece::Const(_) | Piece::Spline(_) | Piece::Sweep { .. } => return None,
        };
        let tau = [t[0] - t0, t[1] - t0];
        let covers = |w: &InputWindow, order: u32, tau: [f64; 2]| w.covers(order, index, tau);
        let fresh = match window {
            Some(w) if covers(w, order, tau) => w,
            _ => {
                let comps = components(piece)?;
                window.insert(InputWindow::build(order, index, &comps, tau[0]))
            }
        };
        let other = also.and_then(|(w, o, t)| {
            let tau_o = t - t0;
            w.as_ref()
                .filter(|w| covers(w, o, [tau_o, tau_o]))
                .map(|w| (w, tau_o))
        });
        let Some(other) = other else {
            return Some((fresh.horner_pair(tau), None));
        };
        // Lanes: the pair, then the other window's value.
        let (w2, tau2) = other;
        let (c2, centre2) = (&w2.coeffs, w2.centre_s);
        let c = [&fresh.coeffs, &fresh.coeffs, c2];
        // Horner in s^2 on the even and the odd coefficients: independent chains.
        let s = [
            tau[0] - fresh.centre_s,
            tau[1] - fresh.centre_s,
            tau2 - centre2,
        ];
        let s2 = [s[0] * s[0], s[1] * s[1], s[2] * s[2]];
        let (mut even, mut odd) = ([0.0; 3], [0.0; 3]);
        for m in (0..=DEGREE / 2).rev() {
            for i in 0..3 {
                even[i] = even[i] * s2[i] + c[i][2 * m];
                if 2 * m < DEGREE {
                    odd[i] = odd[i] * s2[i] + c[i][2 * m + 1];
                }
            }
        }
        let v = [
            even[0] + s[0] * odd[0],
            even[1] + s[1] * odd[1],
            even[2] + s[2] * odd[2],
        ];
        Some(([v[0], v[1]], Some(v[2])))
    }

    /// [`InputWindow::eval_pair`] when `window` already covers both times (it is not
    /// rebuilt), else None: each value is then the one [`InputWindow::eval`] gives at its time,
    /// to the bit, with one pass for both.
    #[inline(always)]
    pub fn eval_pair_covered(
        window: &Option<InputWindow>,
        order: u32,
        index: usize,
        piece: &Piece,
        t: [f64; 2],
    ) -> Option<[f64; 2]> {
        let t0 = match piece {
            Piece::Sine { t0, .. } | Piece::Multisine { t0, .. } => *t0,
            Piece::Const(_) | Piece::Spline(_) | Piece::Sweep { .. } => return None,
        };
        let tau = [t[0] - t0, t[1] - t0];
        window
            .as_ref()
            .filter(|w| w.covers(order, index, tau))
            .map(|w| w.horner_pair(tau))
    }

    /// True when this is the window of `order` of piece `index` and holds at local times `tau`.
    #[inline(always)]
    fn covers(&self, order: u32, index: usize, tau: [f64; 2]) -> bool {
        self.piece == index
            && self.order == order
            && (tau[0] - self.centre_s).abs() <= self.half_width_s
            && (tau[1] - self.centre_s).abs() <= self.half_width_s
    }

    /// The window at two local times (each lane the operations of the three-lane pass).
    fn horner_pair(&self, tau: [f64; 2]) -> [f64; 2] {
        // Horner in s^2 on the even and the odd coefficients: four independent chains.
        let s = [tau[0] - self.centre_s, tau[1] - self.centre_s];
        let s2 = [s[0] * s[0], s[1] * s[1]];
        let (mut even, mut odd) = ([0.0; 2], [0.0; 2]);
        let c = &self.coeffs;
        for m in (0..=DEGREE / 2).rev() {
            for i in 0..2 {
                even[i] = even[i] * s2[i] + c[2 * m];
                if 2 * m < DEGREE {
                    odd[i] = odd[i] * s2[i] + c[2 * m + 1];
                }
            }
        }
        [even[0] + s[0] * odd[0], even[1] + s[1] * odd[1]]
    }
}

/// The interval of a spline that holds at one `t_ref`, for the second derivative of
/// `CubicSpline::eval(t, t_ref)` alone at several times, with the same operations (a replay
/// evaluates only the base acceleration between samples; the value and the velocity cost
/// divisions it does not need). The RK4 stages of a sample interval's sub-steps share their
/// `t_ref`, so a replay looks the interval up once per sample instead of at every stage.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SplineInterval {
    knot_s: f64,
    h: f64,
    m0: f64,
    m1: f64,
}

impl SplineInterval {
    /// None for a spline of fewer than 2 samples (its second derivative is 0).
    pub(crate) fn of(s: &CubicSpline, t_ref: f64) -> Option<SplineInterval> {
        if s.y.len() < 2 {
            return None;
        }
        let i = s.interval(t_ref);
        let h = 1.0 / s.sample_rate_hz;
        Some(SplineInterval {
            knot_s: s.t0 + i as f64 * h,
            h,
            m0: s.m[i],
            m1: s.m[i + 1],
        })
    }

    /// The second derivative at `t` with the cubic of this interval.
    #[inline(always)]
    pub(crate) fn d2(&self, t: f64) -> f64 {
        let u = t - self.knot_s;
        let w = self.h - u;
        self.m0 * w / self.h + self.m1 * u / self.h
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::sim::Multisine;

    #[test]
    fn the_window_is_the_closed_form_to_rounding() {
        let ms = Multisine::band_limited(1.5, 3.5, 0.004, 64, 3, 1300, 100.0);
        let pieces = [
            Piece::Multisine {
                t0: 13.0,
                signal: Arc::new(ms),
            },
            Piece::Sine {
                t0: 2.0,
                amplitude: 0.006,
                omega: 2.0 * std::f64::consts::PI * 3.4,
                phase: 0.7,
            },
        ];
        for (j, piece) in pieces.iter().enumerate() {
            for order in [0, 2] {
                let mut window = None;
                let (mut worst, mut scale) = (0.0_f64, 0.0_f64);
                let mut t = 13.0;
                while t < 26.0 {
                    let d = piece.eval(t, t);
                    let exact = if order == 0 { d.value } else { d.d2 };
                    let fast = InputWindow::eval(&mut window, order, j, piece, t).unwrap();
                    worst = worst.max((fast - exact).abs());
                    scale = scale.max(exact.abs());
                    t += 0.37e-3;
                }
                assert!(
                    worst < 1e-13 * scale,
                    "piece {j}, order {order}: {worst:e} of {scale:e}"
                );
            }
        }
        assert!(InputWindow::eval(&mut None, 2, 0, &Piece::Const(1.0), 0.0).is_none());
    }

    /// The value computed beside a pair is the one `eval` gives later from the same window, to
    /// the bit, and only when that window already covers the time (it is never rebuilt there):
    /// a rig sample's displacement taken from its sub-step is what its channels computed.
    #[test]
    fn the_value_beside_a_pair_is_that_of_eval() {
        let piece = Piece::Sine {
            t0: 2.0,
            amplitude: 0.006,
            omega: 2.0 * std::f64::consts::PI * 3.4,
            phase: 0.7,
        };
        let (mut w_d2, mut w_value) = (None, None);
        let (mut beside, mut checked) = (0, 0);
        let h = 1e-4;
        for k in 0..20_000 {
            let t = 2.0 + k as f64 * h;
            let before = w_value.as_ref().map(|w: &InputWindow| w.centre_s);
            let (pair, value) = InputWindow::eval_pair_with(
                &mut w_d2,
                2,
                0,
                &piece,
                [t + 0.5 * h, t + h],
                Some((&w_value, 0, t + h)),
            )
            .unwrap();
            assert_eq!(before, w_value.as_ref().map(|w| w.centre_s));
            let alone =
                InputWindow::eval_pair(&mut w_d2.clone(), 2, 0, &piece, [t + 0.5 * h, t + h]);
            assert_eq!(pair.map(f64::to_bits), alone.unwrap().map(f64::to_bits));
            let later = InputWindow::eval(&mut w_value, 0, 0, &piece, t + h).unwrap();
            if let Some(v) = value {
                assert_eq!(v.to_bits(), later.to_bits(), "t = {t}");
                checked += 1;
            }
            beside += usize::from(value.is_some());
        }
        // The displacement window is rebuilt every few hundred samples: most values beside.
        assert!(checked > 19_000 && beside == checked, "{checked} of 20000");
    }

    #[test]
    fn spline_interval_d2_is_that_of_eval() {
        use crate::sim::excitation::SplineEnds;
        let y: Vec<f64> = (0..40).map(|i| (0.37 * i as f64).sin()).collect();
        let s = CubicSpline::new(&y, 0.5, 100.0, SplineEnds::NotAKnot);
        for k in 0..500 {
            let t = 0.4 + k as f64 * 0.00083;
            let t_ref = t + 0.002;
            assert_eq!(
                SplineInterval::of(&s, t_ref).unwrap().d2(t).to_bits(),
                s.eval(t, t_ref).d2.to_bits()
            );
        }
    }
}
