//! The free_play family: a contact spring `kfp` beyond a gap that need not be centred,
//! `kfp (x - clamp(x, -neg, pos))`, contact at `+pos` and `-neg`. Real free play is seldom
//! centred on the sensor's zero (a bushing worn on one side, a stop set off-centre): the wide
//! forms plant the total gap split 20/80 to 80/20, and a centred gap fitted to such a one is
//! beaten by x|x| + x^2 on the steps (wide seed 1 cases 11, 137, 150).
//!
//! The search ([`refine`]), each member chosen by the cross-validated force error on the sine
//! steps as every searched parameter is: the centred gap over its grid first
//! ([`super::effects::FREE_PLAY_GAP_FRACTIONS`], built by [`super::effects::structures_on`]),
//! its best refined by golden section between its grid neighbours; then the same total split
//! unevenly ([`SPLITS`]). Only when a split beats the centred gap: each contact point alone over
//! [`CONTACT_FRACTIONS`] with the other held (coordinate descent: the two sides engage apart,
//! so the error is nearly separable in them), at most [`DESCENT_ROUNDS`] rounds, and each
//! refined by golden section. The contact stiffness and every other coefficient are solved by
//! least squares inside each fit. A centred member counts one searched parameter (its width),
//! an uneven one two (its contact points), each beside `kfp`: the penalty counts the shape
//! parameters of the member chosen, as the sensor family's does.

use std::sync::Arc;

use super::effects::{Effect, Structure};
use super::fit::Fitted;
use crate::basis::DeadZone;

/// Contact points searched on each side, relative to the largest relative displacement
/// amplitude: the centred grid's half-gaps (so its best is a point of this grid) and two wider
/// ones, for a side that engages only at the largest steps.
pub const CONTACT_FRACTIONS: [f64; 9] = [0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.65, 0.8];

/// Shares of the total gap on the positive side tried after the centred gap: the wide forms'
/// range (20/80 to 80/20) on steps of a tenth.
pub const SPLITS: [f64; 6] = [0.2, 0.3, 0.4, 0.6, 0.7, 0.8];

/// Rounds of the coordinate descent over the contact grid (each: the positive side, then the
/// negative one).
pub const DESCENT_ROUNDS: usize = 2;

/// Golden-section steps of each refinement: they narrow the bracket of two grid spacings to
/// 0.618^6 = 6 % of it (0.3-1 % of the largest amplitude).
const REFINE_STEPS: usize = 6;

/// Searched-parameter names of the free-play members.
const GAP: &str = "gap_m";
const CONTACT_POS: &str = "contact_pos_m";
const CONTACT_NEG: &str = "contact_neg_m";

/// The free_play member with contact at `+contact_pos_m` and `-contact_neg_m` (both positive).
pub fn structure(contact_neg_m: f64, contact_pos_m: f64) -> Structure {
    let centred = contact_neg_m == contact_pos_m;
    let searched = if centred {
        vec![(GAP.to_string(), contact_neg_m + contact_pos_m)]
    } else {
        vec![
            (CONTACT_POS.to_string(), contact_pos_m),
            (CONTACT_NEG.to_string(), -contact_neg_m),
        ]
    };
    Structure {
        effects: vec![Effect::FreePlay],
        extra_parameters: 1 + searched.len(),
        terms: vec![Arc::new(DeadZone {
            contact_neg_m,
            contact_pos_m,
        })],
        searched,
        ..Structure::default()
    }
}

/// The member's contact points (neg, pos), both positive, from its searched values; None when
/// the structure holds no free play.
pub fn contacts(s: &Structure) -> Option<(f64, f64)> {
    let value = |name: &str| s.searched.iter().find(|(n, _)| n == name).map(|(_, v)| *v);
    if let Some(gap) = value(GAP) {
        return Some((0.5 * gap, 0.5 * gap));
    }
    Some((-value(CONTACT_NEG)?, value(CONTACT_POS)?))
}

/// The fitted gap and contact spring: "contact at +4.70 mm and -1.30 mm (gap 6.00 mm), contact
/// stiffness 4.10 kN/m"; None when the fit holds no free play.
pub fn describe(f: &Fitted) -> Option<String> {
    let (neg, pos) = contacts(&f.structure)?;
    let kfp = f.coefficient("kfp")?;
    let place = if neg == pos {
        format!("centred gap {:.2} mm", 2e3 * pos)
    } else {
        format!(
            "contact at +{:.2} mm and -{:.2} mm (gap {:.2} mm)",
            1e3 * pos,
            1e3 * neg,
            1e3 * (pos + neg)
        )
    };
    Some(format!("{place}, contact stiffness {:.2} kN/m", kfp / 1e3))
}

/// Which contact point a step of the search moves.
#[derive(Clone, Copy)]
enum Side {
    Both,
    Pos,
    Neg,
}

/// The search state: the best member so far, its contact points and error.
struct Best<T> {
    value: T,
    key: f64,
    neg: f64,
    pos: f64,
    /// Contact points already evaluated (the grid's points are revisited by the descent).
    tried: Vec<(f64, f64)>,
}

impl<T> Best<T> {
    fn at(&self, side: Side, c: f64) -> (f64, f64) {
        match side {
            Side::Both => (c, c),
            Side::Pos => (self.neg, c),
            Side::Neg => (c, self.pos),
        }
    }

    /// Evaluates the member at `(neg, pos)` (once) and keeps it if better; its error, infinite
    /// when not physical or tried before.
    fn try_member<E>(
        &mut self,
        (neg, pos): (f64, f64),
        evaluate: &mut impl FnMut(Structure) -> Result<Option<T>, E>,
        key: &impl Fn(&T) -> f64,
    ) -> Result<f64, E> {
        if self.tried.contains(&(neg, pos)) {
            return Ok(f64::INFINITY);
        }
        self.tried.push((neg, pos));
        let Some(t) = evaluate(structure(neg, pos))? else {
            return Ok(f64::INFINITY);
        };
        let k = key(&t);
        if k < self.key {
            *self = Best {
                value: t,
                key: k,
                neg,
                pos,
                tried: std::mem::take(&mut self.tried),
            };
        }
        Ok(k)
    }

    /// Golden-section search of one contact point (or the centred half-gap) between the grid
    /// neighbours of its best value.
    fn golden<E>(
        &mut self,
        side: Side,
        grid: &[f64],
        evaluate: &mut impl FnMut(Structure) -> Result<Option<T>, E>,
        key: &impl Fn(&T) -> f64,
    ) -> Result<(), E> {
        let c0 = match side {
            Side::Neg => self.neg,
            _ => self.pos,
        };
        let i = nearest(grid, c0);
        let a0 = if i > 0 { grid[i - 1] } else { 0.5 * grid[0] };
        let b0 = grid.get(i + 1).copied().unwrap_or(1.25 * grid[i]);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut a, mut b) = (a0, b0);
        let mut c1 = b - g * (b - a);
        let mut c2 = a + g * (b - a);
        let mut f1 = self.try_member(self.at(side, c1), evaluate, key)?;
        let mut f2 = self.try_member(self.at(side, c2), evaluate, key)?;
        for _ in 0..REFINE_STEPS {
            if f1 < f2 {
                b = c2;
                c2 = c1;
                f2 = f1;
                c1 = b - g * (b - a);
                f1 = self.try_member(self.at(side, c1), evaluate, key)?;
            } else {
                a = c1;
                c1 = c2;
                f1 = f2;
                c2 = a + g * (b - a);
                f2 = self.try_member(self.at(side, c2), evaluate, key)?;
            }
        }
        Ok(())
    }
}

/// Index of the grid value nearest `c`.
fn nearest(grid: &[f64], c: f64) -> usize {
    (0..grid.len())
        .min_by(|&i, &j| (grid[i] - c).abs().total_cmp(&(grid[j] - c).abs()))
        .unwrap_or(0)
}

/// The best free-play member from `start`, the best of the centred grid (its structure
/// `member(&start)`), searched as the module doc says: the centred half-gap refined; uneven
/// splits of that total ([`SPLITS`]); only when one of them beats the centred member, coordinate
/// descent of the contact points over [`CONTACT_FRACTIONS`] of `max_displacement_m` and a
/// refinement of each. `evaluate` fits and cross-validates one member (None when it fails or is
/// not physical), `key` is the error it is chosen by. `start` is returned when it holds no free
/// play or nothing beats it.
pub fn refine<T, E>(
    start: T,
    max_displacement_m: f64,
    member: impl Fn(&T) -> &Structure,
    mut evaluate: impl FnMut(Structure) -> Result<Option<T>, E>,
    key: impl Fn(&T) -> f64,
) -> Result<T, E> {
    let Some((neg, pos)) = contacts(member(&start)) else {
        return Ok(start);
    };
    let grid: Vec<f64> = CONTACT_FRACTIONS
        .iter()
        .map(|f| f * max_displacement_m)
        .collect();
    let mut best = Best {
        key: key(&start),
        value: start,
        neg,
        pos,
        tried: vec![(neg, pos)],
    };
    best.golden(Side::Both, &grid, &mut evaluate, &key)?;
    // The split is searched on coarse steps (a fifth of the gap moved across at least), so a
    // centred gap is not made uneven by the noise of a fine search.
    let centred = best.key;
    let total = best.neg + best.pos;
    for share in SPLITS {
        best.try_member((total * (1.0 - share), total * share), &mut evaluate, &key)?;
    }
    if best.key >= centred {
        return Ok(best.value);
    }
    for _ in 0..DESCENT_ROUNDS {
        let before = (best.neg, best.pos);
        for side in [Side::Pos, Side::Neg] {
            for &c in &grid {
                best.try_member(best.at(side, c), &mut evaluate, &key)?;
            }
        }
        if (best.neg, best.pos) == before {
            break;
        }
    }
    best.golden(Side::Pos, &grid, &mut evaluate, &key)?;
    best.golden(Side::Neg, &grid, &mut evaluate, &key)?;
    Ok(best.value)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed-form error with its minimum at contact (neg, pos) = (1.3, 4.7) mm: the search
    /// must land there within its refinement's resolution, from the centred grid's best.
    #[test]
    fn the_search_finds_uneven_contact_points_of_a_separable_error() {
        let (tn, tp) = (1.3e-3, 4.7e-3);
        let err = |s: &Structure| {
            let (n, p) = contacts(s).expect("free play");
            (n - tn).powi(2) + (p - tp).powi(2) + 0.1 * (n - tn) * (p - tp)
        };
        let start = structure(2.0e-3, 2.0e-3);
        let mut evaluations = 0;
        let found = refine(
            start,
            10e-3,
            |s| s,
            |s| {
                evaluations += 1;
                Ok::<_, ()>(Some(s))
            },
            err,
        )
        .expect("no error");
        let (n, p) = contacts(&found).expect("free play");
        assert!((n - tn).abs() < 0.1e-3, "neg {n}");
        assert!((p - tp).abs() < 0.1e-3, "pos {p}");
        assert_eq!(found.extra_parameters, 3);
        // Three refinements of 8, the splits, the grid descent (two rounds of 2 x 8 at most).
        assert!(
            evaluations <= 3 * 8 + 6 + 2 * 16,
            "{evaluations} evaluations"
        );
    }

    #[test]
    fn a_centred_optimum_stays_a_centred_member_with_one_shape_parameter() {
        let t = 2.2e-3;
        let err = |s: &Structure| {
            let (n, p) = contacts(s).expect("free play");
            (n - t).powi(2) + (p - t).powi(2) + 1.5 * (n - t) * (p - t)
        };
        let found = refine(
            structure(2.0e-3, 2.0e-3),
            10e-3,
            |s| s,
            |s| Ok::<_, ()>(Some(s)),
            err,
        )
        .expect("no error");
        let (n, p) = contacts(&found).expect("free play");
        assert_eq!(n, p);
        assert!((n - t).abs() < 0.1e-3, "{n}");
        assert_eq!(found.extra_parameters, 2);
        assert_eq!(found.searched[0].0, GAP);
    }

    #[test]
    fn the_dead_zone_engages_beyond_each_contact_point() {
        use crate::basis::Term;
        let d = DeadZone {
            contact_neg_m: 1e-3,
            contact_pos_m: 3e-3,
        };
        assert_eq!(d.eval(2e-3, 0.0), 0.0);
        assert_eq!(d.eval(-0.5e-3, 0.0), 0.0);
        assert!((d.eval(4e-3, 0.0) - 1e-3).abs() < 1e-15);
        assert!((d.eval(-3e-3, 0.0) + 2e-3).abs() < 1e-15);
    }
}
