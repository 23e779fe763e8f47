//! The hysteresis family: a Bouc-Wen member (yield, n, r) searched from the one-parameter law's
//! best yield ([`refine`]), where the sine steps rank the candidate near the top
//! ([`SHAPE_SEARCH_RANK`]), and the member found, described for the verdict ([`describe`]).

use super::effects::{BOUC_WEN_SHAPES, Structure, hysteresis_structure};
use super::fit::Fitted;
use crate::signal::bouc_wen::HysteresisLaw;

/// The hysteresis candidate's Bouc-Wen shape is searched when it ranks among this many first
/// by step error (fewer than this many candidates have a lower one).
pub const SHAPE_SEARCH_RANK: usize = 3;

/// The Bouc-Wen shape search: the hysteresis family's yield displacement is searched first with
/// the one-parameter law (n = 1, r = 1/2, [`super::effects::HYSTERESIS_YIELD_FRACTIONS`]); then each shape of
/// [`BOUC_WEN_SHAPES`] from that yield, its yield walked by [`YIELD_STEP`] each way while the
/// error falls (at most [`YIELD_STEPS`] steps: the yield and the knee trade off, a sharper knee
/// fitting a later yield, and the error is sharp in the yield, so the grid's steps of 2-2.5 are
/// too coarse to compare shapes on), best by the same error. The member found carries n and r
/// as searched parameters whatever shape won, so the penalised score counts the search (four
/// parameters: alpha, zy, n, r).
///
/// The best member of the family from `start`, the best yield of the one-parameter law (its
/// structure `member(&start)`); `evaluate` fits and cross-validates one member (None when it
/// fails or is not physical), `key` is the error it is chosen by. `start` is returned when it
/// holds no hysteresis or is not the one-parameter law (its shape already chosen).
pub fn refine<T, E>(
    start: T,
    member: impl Fn(&T) -> &Structure,
    mut evaluate: impl FnMut(Structure) -> Result<Option<T>, E>,
    key: impl Fn(&T) -> f64,
) -> Result<T, E> {
    let Some(law) = member(&start).hysteresis else {
        return Ok(start);
    };
    if law.one_parameter_yield_m().is_none() {
        return Ok(start);
    }
    // The start again as a member of the searched family (its score counts n and r).
    let Some(start) = evaluate(hysteresis_structure(law, true))? else {
        return Ok(start);
    };
    let mut best = (key(&start), start);
    for &(n, r) in &BOUC_WEN_SHAPES {
        let at = |yield_m: f64| HysteresisLaw { yield_m, n, r };
        // The shape's best so far: (key, yield).
        let mut shape_best = if at(law.yield_m) == law {
            (best.0, law.yield_m)
        } else {
            match evaluate(hysteresis_structure(at(law.yield_m), true))? {
                Some(c) => {
                    let k = key(&c);
                    if k < best.0 {
                        best = (k, c);
                    }
                    (k, law.yield_m)
                }
                None => (f64::INFINITY, law.yield_m),
            }
        };
        for factor in [1.0 / YIELD_STEP, YIELD_STEP] {
            let mut yield_m = shape_best.1;
            for _ in 0..YIELD_STEPS {
                yield_m *= factor;
                let Some(c) = evaluate(hysteresis_structure(at(yield_m), true))? else {
                    break;
                };
                let k = key(&c);
                if k >= shape_best.0 {
                    break;
                }
                shape_best = (k, yield_m);
                if k < best.0 {
                    best = (k, c);
                }
            }
        }
    }
    Ok(best.1)
}

/// The factor the shape search walks the yield by (a quarter of a doubling) and the most
/// steps it walks each way (a doubling or a halving).
const YIELD_STEP: f64 = 1.189_207_115_002_721;
const YIELD_STEPS: usize = 4;

/// The member of a fitted hysteresis candidate for the verdict: its yield, its shape (n, r; the
/// one-parameter law's when the shape was not searched) and the force it saturates at,
/// alpha zy. None when `f` holds no hysteresis.
pub fn describe(f: &Fitted) -> Option<String> {
    let law = f.structure.hysteresis?;
    let alpha = f.coefficient("alpha")?;
    Some(format!(
        "Bouc-Wen yield {:.2} mm, n {:.2}, r {:.2}, saturated force {:.1} N",
        1e3 * law.yield_m,
        law.n,
        law.r,
        alpha * law.yield_m
    ))
}
