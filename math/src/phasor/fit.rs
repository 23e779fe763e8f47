//! Least-squares multi-harmonic fit on a uniform sampling grid with a known frequency.
//!
//! Model over a window of samples `k = a..b` (sample phase `theta_k = 2 pi nu k`,
//! `nu = f / fs` cycles per sample, referenced to sample index 0):
//!
//! ```text
//! x_k ~ a_0 + sum_{n=1}^{N} ( a_n cos(n theta_k) - b_n sin(n theta_k) ),   C_n = a_n + j b_n
//! ```
//!
//! which is `Re(sum_n C_n e^{j n theta_k})`, the crate's one-sided convention. The parameters
//! are ordered `[a_0, a_1, b_1, a_2, b_2, ...]` (`2N + 1` of them).
//!
//! Cost: the normal matrix `G = U^T U` only needs the exponential sums
//! `E(q) = sum_k e^{j q theta_k}`, `q = 0..=2N`, which are Dirichlet kernels in closed form, so
//! building `G` is `O(N^2)` whatever the window length and the samples are touched once, for the
//! right-hand sides `X_n = sum_k x_k e^{-j n theta_k}` (`O(samples * N)` per channel). The
//! right-hand sides of adjacent windows add up, so a joint fit over several periods reuses
//! the per-period sums.

use num_complex::Complex64;
use std::f64::consts::PI;

/// `sin(pi x)` with the argument reduced first (exact for integer `x`, accurate for large `x`).
fn sin_pi(x: f64) -> f64 {
    let r = x - 2.0 * (x / 2.0).round();
    (PI * r).sin()
}

/// Fractional part in `[0, 1)`.
pub(crate) fn frac(x: f64) -> f64 {
    x - x.floor()
}

/// A uniform grid with `nu` cycles of the fundamental per sample and harmonics `0..=harmonics`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Grid {
    pub nu: f64,
    pub harmonics: usize,
}

/// Index of `a_n` in the parameter vector.
#[inline]
pub(crate) fn idx_a(n: usize) -> usize {
    if n == 0 { 0 } else { 2 * n - 1 }
}

/// Index of `b_n` (n >= 1) in the parameter vector.
#[inline]
pub(crate) fn idx_b(n: usize) -> usize {
    2 * n
}

impl Grid {
    pub fn params(&self) -> usize {
        2 * self.harmonics + 1
    }

    /// `E(q) = sum_{k=start}^{start+len-1} e^{j 2 pi q nu k}` for `q = 0..=2N`.
    fn exp_sums(&self, start: usize, len: usize) -> Vec<Complex64> {
        let centre = start as f64 + (len as f64 - 1.0) / 2.0;
        (0..=2 * self.harmonics)
            .map(|q| {
                if q == 0 {
                    return Complex64::new(len as f64, 0.0);
                }
                let qnu = q as f64 * self.nu;
                // Dirichlet kernel; 0 < q nu < 1 is guaranteed by the harmonic cap.
                let d = sin_pi(qnu * len as f64) / sin_pi(qnu);
                let phase = 2.0 * PI * frac(qnu * centre);
                Complex64::from_polar(d, phase)
            })
            .collect()
    }

    /// Normal matrix `G = U^T U` of the window `start..start + len` (row-major).
    pub fn normal_matrix(&self, start: usize, len: usize) -> Vec<f64> {
        let e = self.exp_sums(start, len);
        let n_max = self.harmonics;
        // Sums of products of cos/sin of m theta and n theta (m, n >= 0).
        let re = |q: usize| e[q].re;
        let im_signed = |m: usize, n: usize| -> f64 {
            // Im E(m - n) with E(-q) = conj(E(q)).
            if m >= n { e[m - n].im } else { -e[n - m].im }
        };
        let cc = |m: usize, n: usize| 0.5 * (re(m.abs_diff(n)) + re(m + n));
        let ss = |m: usize, n: usize| 0.5 * (re(m.abs_diff(n)) - re(m + n));
        let sc = |m: usize, n: usize| 0.5 * (e[m + n].im + im_signed(m, n)); // sum sin(m) cos(n)
        let p = self.params();
        let mut g = vec![0.0; p * p];
        let mut set = |i: usize, j: usize, v: f64| g[i * p + j] = v;
        for m in 0..=n_max {
            for n in 0..=n_max {
                set(idx_a(m), idx_a(n), cc(m, n));
                if n >= 1 {
                    // u_{b_n} = -sin(n theta)
                    set(idx_a(m), idx_b(n), -sc(n, m));
                    set(idx_b(n), idx_a(m), -sc(n, m));
                }
                if m >= 1 && n >= 1 {
                    set(idx_b(m), idx_b(n), ss(m, n));
                }
            }
        }
        g
    }

    /// Accumulates `X_n = sum_k x_k e^{-j n theta_k}` over `range` for every channel into
    /// `re`/`im` (layout `[channel * (N + 1) + n]`) and `sum x_k^2` into `sumsq`.
    ///
    /// The vector `e^{-j n theta_k}` (`n = 0..=N`) is advanced from sample to sample by an
    /// element-wise rotation (vectorisable, no per-sample trigonometry) and re-anchored exactly
    /// every [`ANCHOR`] samples from the start of `range`, so rounding drift stays below
    /// `~ANCHOR * eps`. [`Rotor`] holds the rule, so a stream fed sample by sample gives the same
    /// sums to the last bit.
    pub fn accumulate(
        &self,
        channels: &[&[f64]],
        range: std::ops::Range<usize>,
        re: &mut [f64],
        im: &mut [f64],
        sumsq: &mut [f64],
    ) {
        let h = self.harmonics + 1;
        assert!(
            re.len() == channels.len() * h && im.len() == re.len() && sumsq.len() == channels.len()
        );
        let mut rotor = Rotor::new(self);
        let mut k0 = range.start;
        while k0 < range.end {
            let k1 = (k0 + ANCHOR).min(range.end);
            rotor.anchor(k0);
            for k in k0..k1 {
                for ((x, (acc_r, acc_i)), sq) in channels
                    .iter()
                    .zip(re.chunks_exact_mut(h).zip(im.chunks_exact_mut(h)))
                    .zip(sumsq.iter_mut())
                {
                    rotor.add(x[k], acc_r, acc_i, sq);
                }
                rotor.advance();
            }
            k0 = k1;
        }
    }
}

/// Samples between exact re-anchorings of a [`Rotor`], counted from the start of a window.
pub(crate) const ANCHOR: usize = 128;

/// The vector `e^{-j n theta_k}`, `n = 0..=N`, at the current sample `k`, advanced by one
/// sample with an element-wise rotation and set exactly with [`Rotor::anchor`].
#[derive(Clone)]
pub(crate) struct Rotor {
    nu: f64,
    /// `e^{-j n 2 pi nu}`: one sample's rotation of each harmonic.
    dr: Vec<f64>,
    di: Vec<f64>,
    wr: Vec<f64>,
    wi: Vec<f64>,
}

impl Rotor {
    /// A rotor of `grid`, anchored at sample 0.
    pub fn new(grid: &Grid) -> Rotor {
        let h = grid.harmonics + 1;
        let (dr, di): (Vec<f64>, Vec<f64>) = (0..h)
            .map(|n| {
                let (s, c) = (2.0 * PI * frac(n as f64 * grid.nu)).sin_cos();
                (c, -s)
            })
            .unzip();
        let mut r = Rotor {
            nu: grid.nu,
            dr,
            di,
            wr: vec![0.0; h],
            wi: vec![0.0; h],
        };
        r.anchor(0);
        r
    }

    /// Sets the vector exactly at sample `k` (phase reduced to one cycle first).
    pub fn anchor(&mut self, k: usize) {
        let ph = frac(k as f64 * self.nu);
        for (n, (wr, wi)) in self.wr.iter_mut().zip(self.wi.iter_mut()).enumerate() {
            let (s, c) = (2.0 * PI * frac(n as f64 * ph)).sin_cos();
            *wr = c;
            *wi = -s;
        }
    }

    /// Adds sample `x` of one channel at the current sample: `acc += x e^{-j n theta_k}`.
    #[inline]
    pub fn add(&self, x: f64, acc_r: &mut [f64], acc_i: &mut [f64], sq: &mut f64) {
        *sq += x * x;
        for ((r, i), (a, b)) in acc_r
            .iter_mut()
            .zip(acc_i.iter_mut())
            .zip(self.wr.iter().zip(&self.wi))
        {
            *r += x * a;
            *i += x * b;
        }
    }

    /// Moves to the next sample.
    #[inline]
    pub fn advance(&mut self) {
        for ((a, b), (c, d)) in self
            .wr
            .iter_mut()
            .zip(self.wi.iter_mut())
            .zip(self.dr.iter().zip(&self.di))
        {
            let (ar, ai) = (*a, *b);
            *a = ar * c - ai * d;
            *b = ar * d + ai * c;
        }
    }
}

/// Right-hand sides (channel-major: `[channel * (2N + 1) + param]`) from the accumulated `X_n`.
pub(crate) fn rhs_matrix(harmonics: usize, n_channels: usize, re: &[f64], im: &[f64]) -> Vec<f64> {
    let h = harmonics + 1;
    let p = 2 * harmonics + 1;
    let mut r = vec![0.0; p * n_channels];
    for c in 0..n_channels {
        r[c * p] = re[c * h];
        for n in 1..h {
            r[c * p + idx_a(n)] = re[c * h + n];
            r[c * p + idx_b(n)] = im[c * h + n];
        }
    }
    r
}

/// Phasors `C_0..=C_N` of channel `c` of a solution (channel-major like [`rhs_matrix`]).
pub(crate) fn phasors_of(beta: &[f64], c: usize, harmonics: usize) -> Vec<Complex64> {
    let b = &beta[c * (2 * harmonics + 1)..(c + 1) * (2 * harmonics + 1)];
    (0..=harmonics)
        .map(|n| {
            if n == 0 {
                Complex64::new(b[0], 0.0)
            } else {
                Complex64::new(b[idx_a(n)], b[idx_b(n)])
            }
        })
        .collect()
}

/// Dot product with four independent accumulators (vectorises without reassociation flags).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (ca, ra) = a[..n].as_chunks::<4>();
    let (cb, rb) = b[..n].as_chunks::<4>();
    let mut acc = [0.0; 4];
    for (x, y) in ca.iter().zip(cb) {
        for l in 0..4 {
            acc[l] += x[l] * y[l];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}

/// Cholesky factor `G = L L^T` of a small dense symmetric positive definite matrix; `L` and
/// `L^T` are both kept row-major so that both substitutions run over contiguous memory.
#[derive(Clone)]
pub(crate) struct Factor {
    p: usize,
    l: Vec<f64>,
    lt: Vec<f64>,
}

impl Factor {
    /// `None` if `g` (row-major `p x p`) is not numerically positive definite.
    pub fn new(g: &[f64], p: usize) -> Option<Factor> {
        let mut l = vec![0.0; p * p];
        for i in 0..p {
            for j in 0..=i {
                let v = g[i * p + j] - dot(&l[i * p..i * p + j], &l[j * p..j * p + j]);
                if i == j {
                    if !(v > 0.0 && v.is_finite()) {
                        return None;
                    }
                    l[i * p + i] = v.sqrt();
                } else {
                    l[i * p + j] = v / l[j * p + j];
                }
            }
        }
        let mut lt = vec![0.0; p * p];
        for i in 0..p {
            for j in 0..=i {
                lt[j * p + i] = l[i * p + j];
            }
        }
        Some(Factor { p, l, lt })
    }

    /// Solves `G x = b` in place for each length-`p` block of `b` (one block per channel).
    pub fn solve(&self, b: &mut [f64]) {
        let p = self.p;
        for x in b.chunks_exact_mut(p) {
            // Forward: L y = b.
            for i in 0..p {
                x[i] = (x[i] - dot(&self.l[i * p..i * p + i], &x[..i])) / self.l[i * p + i];
            }
            // Backward: L^T x = y.
            for i in (0..p).rev() {
                x[i] = (x[i] - dot(&self.lt[i * p + i + 1..(i + 1) * p], &x[i + 1..]))
                    / self.l[i * p + i];
            }
        }
    }

    /// Diagonal of `G^{-1}` (`= sum_k (L^{-1})_{k i}^2`).
    pub fn inverse_diagonal(&self) -> Vec<f64> {
        let p = self.p;
        let mut diag = vec![0.0; p];
        let mut y = vec![0.0; p];
        for i in 0..p {
            // Column i of L^{-1}: solve L y = e_i (zero above row i).
            y.iter_mut().for_each(|v| *v = 0.0);
            for k in i..p {
                let rhs = if k == i { 1.0 } else { 0.0 };
                y[k] = (rhs - dot(&self.l[k * p + i..k * p + k], &y[i..k])) / self.l[k * p + k];
            }
            diag[i] = dot(&y, &y);
        }
        diag
    }
}

/// Cholesky factors of per-window normal matrices, shared between windows of the same length
/// and the same starting phase (to 1e-12 of a cycle), e.g. 2 kinds for 62.5 samples per period,
/// each with the diagonal of its inverse once asked for (the noise of a per-period phasor).
#[derive(Clone)]
pub(crate) struct FactorCache {
    entries: Vec<CachedFactor>,
}

#[derive(Clone)]
struct CachedFactor {
    len: usize,
    phase: f64,
    factor: Factor,
    inverse_diagonal: Option<Vec<f64>>,
}

impl FactorCache {
    pub fn new() -> Self {
        FactorCache {
            entries: Vec::new(),
        }
    }

    fn entry(&mut self, grid: &Grid, start: usize, len: usize) -> Option<&mut CachedFactor> {
        let phase = frac(start as f64 * grid.nu);
        let hit = self.entries.iter().position(|e| {
            let d = (e.phase - phase).abs();
            e.len == len && d.min(1.0 - d) < 1e-12
        });
        let i = match hit {
            Some(i) => i,
            None => {
                let factor = Factor::new(&grid.normal_matrix(start, len), grid.params())?;
                self.entries.push(CachedFactor {
                    len,
                    phase,
                    factor,
                    inverse_diagonal: None,
                });
                self.entries.len() - 1
            }
        };
        Some(&mut self.entries[i])
    }

    pub fn get(&mut self, grid: &Grid, start: usize, len: usize) -> Option<&Factor> {
        Some(&self.entry(grid, start, len)?.factor)
    }

    /// [`Factor::inverse_diagonal`] of the window's factor, computed once per factor.
    pub fn inverse_diagonal(&mut self, grid: &Grid, start: usize, len: usize) -> Option<&[f64]> {
        let e = self.entry(grid, start, len)?;
        Some(
            e.inverse_diagonal
                .get_or_insert_with(|| e.factor.inverse_diagonal()),
        )
    }
}
