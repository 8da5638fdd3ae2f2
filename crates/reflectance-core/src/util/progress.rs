//! Cooperative progress reporting and cancellation of long runs: the library reports to an
//! [`Observer`]; the command line shows it on stderr, the server's jobs through the admin
//! API. Nothing here prints.

/// Cooperative progress reporting and cancellation for long runs (the server's jobs).
/// Long operations call [`Observer::progress`] after each unit of work (an image, a fold)
/// and check [`Observer::cancelled`] before starting the next one; a unit that has started
/// runs to completion.
pub trait Observer: Sync {
    /// A new stage of the run begins (`"features"`, `"fit"`, `"cross_validate"`, …).
    fn stage(&self, _name: &'static str) {}
    /// `done` of `total` units of the current stage are complete.
    fn progress(&self, _done: usize, _total: usize) {}
    /// Whether the run should stop before its next unit of work.
    fn cancelled(&self) -> bool {
        false
    }
}

/// Observes nothing and never cancels: what the plain entry points use.
pub struct Silent;

impl Observer for Silent {}

/// Counts completed units across threads and reports each completion.
pub struct Counter<'a> {
    observer: &'a dyn Observer,
    done: std::sync::atomic::AtomicUsize,
    total: usize,
}

impl<'a> Counter<'a> {
    /// A counter of `total` units reporting to `observer` (0 done, at once).
    pub fn new(observer: &'a dyn Observer, total: usize) -> Self {
        observer.progress(0, total);
        Counter {
            observer,
            done: std::sync::atomic::AtomicUsize::new(0),
            total,
        }
    }

    /// One more unit is complete.
    pub fn tick(&self) {
        let done = self.done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        self.observer.progress(done, self.total);
    }

    /// A guard that counts one unit when it goes out of scope (also when a unit panics
    /// through it, so the count never stalls below a finished run).
    pub fn ticks_when_dropped(&self) -> Tick<'_, 'a> {
        Tick(self)
    }

    /// Whether the observer asked to stop.
    pub fn cancelled(&self) -> bool {
        self.observer.cancelled()
    }
}

/// Counts one unit of its [`Counter`] when dropped.
pub struct Tick<'c, 'a>(&'c Counter<'a>);

impl Drop for Tick<'_, '_> {
    fn drop(&mut self) {
        self.0.tick();
    }
}
