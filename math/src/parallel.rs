//! Independent work over a slice on the machine's cores, the results in the slice's order: the
//! same results as one loop (each item's work is the same code on the same data, and nothing
//! is summed across parts), in less wall time on a long input. Short inputs stay on the calling
//! thread.

use std::num::NonZeroUsize;

/// Samples a part should hold at least before work is split: below this a thread's start costs
/// more than it saves.
pub const PART_MIN_SAMPLES: usize = 20_000;

/// The threads work is split over: one per available core, at most 8.
pub fn threads() -> usize {
    std::thread::available_parallelism()
        .map_or(1, NonZeroUsize::get)
        .min(8)
}

/// `f` over contiguous parts of `items`, each at least `min_part` items long, one part per
/// thread of [`threads`]; the parts' results concatenated in order.
pub fn in_parts<T: Sync, R: Send>(
    items: &[T],
    min_part: usize,
    f: impl Fn(&[T]) -> Vec<R> + Sync,
) -> Vec<R> {
    in_parts_on(threads(), items, min_part, f)
}

/// [`in_parts`] of work that may fail: the error of the first part that failed (each part stops
/// at its first error, so this is the first error in the items' order).
pub fn try_in_parts<T: Sync, R: Send, E: Send>(
    items: &[T],
    min_part: usize,
    f: impl Fn(&[T]) -> Result<Vec<R>, E> + Sync,
) -> Result<Vec<R>, E> {
    try_in_parts_on(threads(), items, min_part, f)
}

/// [`in_parts`] on `threads` threads.
pub fn in_parts_on<T: Sync, R: Send>(
    threads: usize,
    items: &[T],
    min_part: usize,
    f: impl Fn(&[T]) -> Vec<R> + Sync,
) -> Vec<R> {
    let parts = threads.min(items.len() / min_part.max(1)).max(1);
    if parts == 1 {
        return f(items);
    }
    let size = items.len().div_ceil(parts);
    std::thread::scope(|scope| {
        let f = &f;
        let others: Vec<_> = items[size..]
            .chunks(size)
            .map(|part| scope.spawn(move || f(part)))
            .collect();
        let mut out = f(&items[..size]);
        for h in others {
            // A part's panic is this call's panic.
            out.extend(h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)));
        }
        out
    })
}

/// [`try_in_parts`] on `threads` threads.
pub fn try_in_parts_on<T: Sync, R: Send, E: Send>(
    threads: usize,
    items: &[T],
    min_part: usize,
    f: impl Fn(&[T]) -> Result<Vec<R>, E> + Sync,
) -> Result<Vec<R>, E> {
    let mut out = Vec::with_capacity(items.len());
    for part in in_parts_on(threads, items, min_part, |part| vec![f(part)]) {
        out.extend(part?);
    }
    Ok(out)
}

/// The items a part should hold for [`PART_MIN_SAMPLES`], with `samples` samples in `items`
/// items in all.
pub fn min_part_of(samples: usize, items: usize) -> usize {
    let per_item = samples.div_ceil(items.max(1)).max(1);
    PART_MIN_SAMPLES.div_ceil(per_item)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_give_the_loops_results_in_order_and_its_first_error() {
        let items: Vec<u64> = (0..1000).collect();
        let f = |x: &u64| x.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(17);
        let expected: Vec<u64> = items.iter().map(f).collect();
        for threads in [1, 2, 3, 7] {
            for min_part in [1, 10, 333, 2000] {
                let got = in_parts_on(threads, &items, min_part, |p| p.iter().map(f).collect());
                assert_eq!(got, expected, "{threads} threads, parts of {min_part}");
                let failing = |p: &[u64]| -> Result<Vec<u64>, u64> {
                    p.iter()
                        .map(|&x| if x % 400 == 399 { Err(x) } else { Ok(f(&x)) })
                        .collect()
                };
                assert_eq!(
                    try_in_parts_on(threads, &items, min_part, failing),
                    Err(399),
                    "{threads} threads"
                );
            }
        }
        assert_eq!(min_part_of(1_000_000, 1000), 20);
        assert_eq!(min_part_of(0, 0), PART_MIN_SAMPLES);
    }
}
