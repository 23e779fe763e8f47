//! The world's element: the rig's base element (a [`TruthElement`], linear with or without
//! Coulomb friction) plus terms written here in forms wider than the diagnosis's candidates
//! (a Stribeck curve with its own exponent, unequal free-play gaps, Bouc-Wen with its shape
//! parameters, ...). Nothing here is shared with the candidates' forms: the evaluation then
//! tests what happens when the world is not the model.

use forcemap_math::element::{Element, Friction};
use forcemap_math::sim::TruthElement;
use serde::Serialize;

/// One term of the world's element force.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "term", rename_all = "snake_case")]
pub enum Term {
    /// Coulomb friction whose level differs by direction: `level (1 + sgn(v) asymmetry)`.
    Coulomb { level_n: f64, asymmetry: f64 },
    /// Stribeck excess over the base friction with its own shape exponent: slip force
    /// `sgn(v) (Fc + excess exp(-|v / vs|^exponent))` (the library's form is exponent 2).
    Stribeck {
        excess_n: f64,
        velocity_mps: f64,
        exponent: f64,
    },
    /// `coef sgn(u) |u|^exponent` of the displacement (`on_velocity` false) or velocity.
    OddPower {
        coef: f64,
        exponent: f64,
        on_velocity: bool,
    },
    /// Extra damping by direction: `rebound v` for v > 0, `compression v` for v < 0.
    AsymmetricDamping {
        rebound_n_s_per_m: f64,
        compression_n_s_per_m: f64,
    },
    /// A contact spring beyond `gap_pos_m` (x > 0) and `gap_neg_m` (x < 0, a positive width).
    FreePlay {
        gap_neg_m: f64,
        gap_pos_m: f64,
        stiffness_n_per_m: f64,
    },
    /// Bouc-Wen `alpha z`, `z' = v - beta |v| |z|^(n-1) z - gamma v |z|^n` (one state).
    BoucWen {
        alpha_n_per_m: f64,
        beta: f64,
        gamma: f64,
        n: f64,
    },
    /// The base damper in series with a spring (oil compressibility, a rubber mount): its
    /// force f obeys `f' = k (v - f / c)` (one state) and replaces `c v`.
    SeriesCompliance {
        damping_n_s_per_m: f64,
        stiffness_n_per_m: f64,
    },
    /// The base damping fades with the energy it dissipated: `c = c0 (1 - fade E)`, `E' = c v^2`
    /// (one state, J, counted from `energy_at_start_j`: a replay of a later record starts with
    /// what the run dissipated before it); adds `-c0 fade E v` to the base `c0 v`.
    Drift {
        damping_n_s_per_m: f64,
        fade_per_j: f64,
        energy_at_start_j: f64,
    },
    /// Position-periodic cogging `amplitude sin(2 pi x / pitch + phase)`.
    Cogging {
        amplitude_n: f64,
        pitch_m: f64,
        phase_rad: f64,
    },
    /// A frequency-dependent elastomer stiffness: four Maxwell branches (spring `k_i` in series
    /// with a dashpot, relaxation times 0.01-0.64 s, `k_i = stiffness (tau_i / 0.04 s)^-order`),
    /// a Prony series approximating a fractional derivative of order `order` (four states).
    Elastomer { stiffness_n_per_m: f64, order: f64 },
}

/// The relaxation times of [`Term::Elastomer`]'s branches [s].
pub const ELASTOMER_TAUS_S: [f64; 4] = [0.01, 0.04, 0.16, 0.64];

impl Term {
    /// The term as a replay starting after the run accumulated `v2_integral` (the integral of
    /// the squared relative velocity [m^2/s]) sees it: a drift starts with the energy its
    /// damper dissipated by then, `E = (1 - exp(-fade c0 I)) / fade` (from
    /// `E' = c0 (1 - fade E) v^2`); every other term is unchanged.
    pub fn at_dissipation(&self, v2_integral: f64) -> Term {
        match *self {
            Term::Drift {
                damping_n_s_per_m,
                fade_per_j,
                ..
            } => Term::Drift {
                damping_n_s_per_m,
                fade_per_j,
                energy_at_start_j: if fade_per_j > 0.0 {
                    -(-fade_per_j * damping_n_s_per_m * v2_integral).exp_m1() / fade_per_j
                } else {
                    damping_n_s_per_m * v2_integral
                },
            },
            t => t,
        }
    }

    fn states(&self) -> usize {
        match self {
            Term::BoucWen { .. } | Term::SeriesCompliance { .. } | Term::Drift { .. } => 1,
            Term::Elastomer { .. } => ELASTOMER_TAUS_S.len(),
            _ => 0,
        }
    }

    fn force(&self, x: f64, v: f64, z: &[f64]) -> f64 {
        match *self {
            Term::Coulomb { .. } => 0.0,
            Term::Stribeck {
                excess_n,
                velocity_mps,
                exponent,
            } => {
                // The friction law holds up to Fc + excess while stuck (see `friction`); while
                // slipping the excess decays: this smooth part removes what has decayed, and
                // is continuous (zero) at v = 0.
                -v.signum() * excess_n * (1.0 - (-(v / velocity_mps).abs().powf(exponent)).exp())
            }
            Term::OddPower {
                coef,
                exponent,
                on_velocity,
            } => {
                let u = if on_velocity { v } else { x };
                coef * u.signum() * u.abs().powf(exponent)
            }
            Term::AsymmetricDamping {
                rebound_n_s_per_m,
                compression_n_s_per_m,
            } => {
                if v > 0.0 {
                    rebound_n_s_per_m * v
                } else {
                    compression_n_s_per_m * v
                }
            }
            Term::FreePlay {
                gap_neg_m,
                gap_pos_m,
                stiffness_n_per_m,
            } => {
                if x > gap_pos_m {
                    stiffness_n_per_m * (x - gap_pos_m)
                } else if x < -gap_neg_m {
                    stiffness_n_per_m * (x + gap_neg_m)
                } else {
                    0.0
                }
            }
            Term::BoucWen { alpha_n_per_m, .. } => alpha_n_per_m * z[0],
            Term::SeriesCompliance {
                damping_n_s_per_m, ..
            } => z[0] - damping_n_s_per_m * v,
            Term::Drift {
                damping_n_s_per_m,
                fade_per_j,
                energy_at_start_j,
            } => -damping_n_s_per_m * (fade_per_j * (energy_at_start_j + z[0])).min(1.0) * v,
            Term::Cogging {
                amplitude_n,
                pitch_m,
                phase_rad,
            } => amplitude_n * (std::f64::consts::TAU * x / pitch_m + phase_rad).sin(),
            Term::Elastomer { .. } => z.iter().sum(),
        }
    }

    fn rates(&self, v: f64, z: &[f64], dz: &mut [f64]) {
        match *self {
            Term::BoucWen { beta, gamma, n, .. } => {
                let azn = z[0].abs().powf(n);
                dz[0] = v - beta * v.abs() * z[0].signum() * azn - gamma * v * azn;
            }
            Term::SeriesCompliance {
                damping_n_s_per_m,
                stiffness_n_per_m,
            } => dz[0] = stiffness_n_per_m * (v - z[0] / damping_n_s_per_m),
            Term::Drift {
                damping_n_s_per_m,
                fade_per_j,
                energy_at_start_j,
            } => {
                let fade = fade_per_j * (energy_at_start_j + z[0]);
                dz[0] = damping_n_s_per_m * (1.0 - fade).max(0.0) * v * v;
            }
            Term::Elastomer {
                stiffness_n_per_m,
                order,
            } => {
                for (i, tau) in ELASTOMER_TAUS_S.iter().enumerate() {
                    let k = stiffness_n_per_m * (tau / 0.04).powf(-order);
                    // A spring k in series with a dashpot k tau: f' = k v - f / tau.
                    dz[i] = k * v - z[i] / tau;
                }
            }
            _ => {}
        }
    }
}

/// The world's element: `base` plus `terms`.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldElement {
    pub base: TruthElement,
    pub terms: Vec<Term>,
}

impl Element for WorldElement {
    fn smooth_force(&self, x: f64, v: f64, z: &[f64]) -> f64 {
        let nb = self.base.internal_states();
        let mut f = self.base.smooth_force(x, v, &z[..nb]);
        let mut at = nb;
        for t in &self.terms {
            let n = t.states();
            f += t.force(x, v, &z[at..at + n]);
            at += n;
        }
        f
    }

    fn friction(&self) -> Option<Friction> {
        let mut f = self.base.friction();
        for t in &self.terms {
            match *t {
                Term::Coulomb { level_n, asymmetry } => {
                    f = Some(Friction {
                        asymmetry,
                        ..Friction::coulomb(level_n)
                    });
                }
                Term::Stribeck { excess_n, .. } => {
                    if let Some(fr) = f.as_mut() {
                        // Held up to the kinetic level plus the excess while stuck; the slip
                        // law stays plain Coulomb here (breakaway == kinetic would be read as
                        // no Stribeck), its decay lives in `Term::force`.
                        fr.breakaway_n += excess_n;
                        fr.kinetic_n += excess_n;
                    }
                }
                _ => {}
            }
        }
        f
    }

    fn internal_states(&self) -> usize {
        self.base.internal_states() + self.terms.iter().map(Term::states).sum::<usize>()
    }

    fn internal_rates(&self, x: f64, v: f64, z: &[f64], dz: &mut [f64]) {
        let nb = self.base.internal_states();
        self.base.internal_rates(x, v, &z[..nb], &mut dz[..nb]);
        let mut at = nb;
        for t in &self.terms {
            let n = t.states();
            t.rates(v, &z[at..at + n], &mut dz[at..at + n]);
            at += n;
        }
    }

    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        if self.terms.is_empty() {
            self.base.linear_coefficients()
        } else {
            None
        }
    }
}
