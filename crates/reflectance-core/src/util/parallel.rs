//! One request's hot loops split between the machine's cores, with results in the order one
//! thread would give them (so the same bits whatever the split).
//!
//! Scoped threads, not the server's rayon pool: a pool thread waiting on a stolen part may
//! take up another request meanwhile and hold this one's answer behind it.

use std::ops::Range;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Most parts a loop is split into: a server runs a request per core already, and a lone
/// request gains little past a few.
const MAX_PARTS: usize = 4;

/// Units of work running now that hold a core each (a server's requests, [`Running`]).
static RUNNING: AtomicUsize = AtomicUsize::new(0);

/// Held while a unit of work runs on a core of its own (the server holds one per request):
/// a loop splits only over the cores no other unit holds, so that a busy server does not pay
/// for threads its cores have no room for.
pub struct Running(());

impl Running {
    /// A unit of work starts; it ends when this is dropped.
    pub fn start() -> Running {
        RUNNING.fetch_add(1, Ordering::Relaxed);
        Running(())
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        RUNNING.fetch_sub(1, Ordering::Relaxed);
    }
}

/// The cores this process may run on (its affinity and cgroup quota).
fn cores() -> usize {
    static CORES: OnceLock<usize> = OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// Parts a hot loop is split into now: the cores this process may run on shared among the
/// units [`Running`], at most [`MAX_PARTS`], at least one.
pub fn parts() -> usize {
    (cores() / RUNNING.load(Ordering::Relaxed).max(1)).clamp(1, MAX_PARTS)
}

/// Below this many pixels (or values) a loop stays on one thread: a thread costs tens of
/// microseconds to start, what such a loop takes whole.
const MIN_TO_SPLIT: usize = 1 << 17;

/// [`parts`] for a loop over `n` pixels or values: 1 when it is too short to split.
pub fn parts_for(n: usize) -> usize {
    if n >= MIN_TO_SPLIT { parts() } else { 1 }
}

/// Every value of `values` replaced by `f` of it, the values dealt in runs among `parts`
/// threads.
pub fn update_in_parts(parts: usize, values: &mut [f64], f: impl Fn(f64) -> f64 + Sync) {
    fill_rows_in_parts(parts, values, 1, |_, run| {
        run.iter_mut().for_each(|v| *v = f(*v))
    });
}

/// `work(part, parts)` for each of `parts` parts, the first on this thread and the others on
/// threads of their own; the results in part order. A panic in a part is this call's panic.
pub fn in_parts<T: Send>(parts: usize, work: impl Fn(usize, usize) -> T + Sync) -> Vec<T> {
    let parts = parts.max(1);
    if parts == 1 {
        return vec![work(0, 1)];
    }
    std::thread::scope(|scope| {
        let work = &work;
        let helpers: Vec<_> = (1..parts)
            .map(|part| scope.spawn(move || work(part, parts)))
            .collect();
        let mut results = vec![work(0, parts)];
        for helper in helpers {
            results.push(
                helper
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            );
        }
        results
    })
}

/// `out`, rows of `width` values, filled by `band(rows, its part of out)` in bands of rows dealt
/// among `parts` threads. The output is this thread's, so the parts allocate no copy of it.
pub fn fill_rows_in_parts<T: Send>(
    parts: usize,
    out: &mut [T],
    width: usize,
    band: impl Fn(Range<usize>, &mut [T]) + Sync,
) {
    let h = out.len() / width.max(1);
    let per_band = h.div_ceil(parts.max(1)).max(1);
    let band = &band;
    std::thread::scope(|scope| {
        let mut bands = out
            .chunks_mut(per_band * width.max(1))
            .enumerate()
            .map(|(k, chunk)| (k * per_band..((k + 1) * per_band).min(h), chunk));
        let first = bands.next();
        let helpers: Vec<_> = bands
            .map(|(rows, chunk)| scope.spawn(move || band(rows, chunk)))
            .collect();
        if let Some((rows, chunk)) = first {
            band(rows, chunk);
        }
        for helper in helpers {
            helper
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        }
    });
}

/// What `band(rows, out)` pushes for every row of `0..h`, in row order, the rows dealt in
/// bands among `parts` threads.
pub fn rows_in_parts<T: Send>(
    h: usize,
    parts: usize,
    band: impl Fn(Range<usize>, &mut Vec<T>) + Sync,
) -> Vec<T> {
    let per_band = h.div_ceil(parts.max(1)).max(1);
    joined(in_parts(h.div_ceil(per_band), |part, _| {
        let mut out = Vec::new();
        band(part * per_band..((part + 1) * per_band).min(h), &mut out);
        out
    }))
}

/// The parts' results one after the other (the one part's moved, not copied).
pub fn joined<T>(mut parts: Vec<Vec<T>>) -> Vec<T> {
    match parts.len() {
        1 => parts.pop().unwrap_or_default(),
        _ => parts.into_iter().flatten().collect(),
    }
}

/// `f` of every item, in the items' order, the items dealt among `parts` parts in turn.
pub fn map_in_parts<I: Sync, T: Send>(
    parts: usize,
    items: &[I],
    f: impl Fn(&I) -> T + Sync,
) -> Vec<T> {
    let mut dealt: Vec<std::vec::IntoIter<T>> = in_parts(parts.min(items.len()), |part, n| {
        items
            .iter()
            .skip(part)
            .step_by(n)
            .map(&f)
            .collect::<Vec<T>>()
    })
    .into_iter()
    .map(Vec::into_iter)
    .collect();
    let n = dealt.len();
    (0..items.len())
        .filter_map(|k| dealt[k % n].next())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_parts_results_come_in_the_order_one_thread_gives() {
        let items: Vec<u64> = (0..23).collect();
        let square = |v: &u64| v * v + 1;
        let one: Vec<u64> = items.iter().map(square).collect();
        for parts in 1..=5 {
            assert_eq!(map_in_parts(parts, &items, square), one, "{parts} parts");
        }
        assert!(map_in_parts(3, &[] as &[u64], square).is_empty());
        for parts in 1..=5 {
            let rows = rows_in_parts(7, parts, |rows, out| {
                rows.for_each(|y| out.extend(std::iter::repeat_n(y, y % 3)))
            });
            assert_eq!(rows, [1, 2, 2, 4, 5, 5], "{parts} parts");
        }
        for parts in 1..=5 {
            let mut rows = vec![0; 7 * 3];
            fill_rows_in_parts(parts, &mut rows, 3, |ys, band| {
                for (y, row) in ys.zip(band.chunks_mut(3)) {
                    row.fill(y);
                }
            });
            assert_eq!(
                rows,
                (0..21).map(|i| i / 3).collect::<Vec<_>>(),
                "{parts} parts"
            );
        }
        for parts in 1..=5 {
            let mut values: Vec<f64> = (0..23).map(f64::from).collect();
            update_in_parts(parts, &mut values, |v| v * v + 1.0);
            assert!(values.iter().zip(&one).all(|(&v, &o)| v == o as f64));
        }
        let threads = in_parts(3, |part, n| (part, n, std::thread::current().id()));
        assert_eq!(
            threads.iter().map(|t| (t.0, t.1)).collect::<Vec<_>>(),
            [(0, 3), (1, 3), (2, 3)]
        );
        assert_ne!(
            threads[0].2, threads[1].2,
            "a part runs on a thread of its own"
        );
    }

    #[test]
    fn a_part_that_panics_is_the_callers_panic() {
        let caught = std::panic::catch_unwind(|| {
            in_parts(2, |part, _| {
                assert!(part == 0, "part {part} fails");
                part
            })
        });
        assert!(caught.is_err());
    }
}
