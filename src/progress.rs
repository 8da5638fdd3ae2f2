//! Progress of the command line's long runs on stderr: a bar when stderr is a terminal,
//! otherwise plain lines at most every [`LINE_INTERVAL`] (or `REFLECTANCE_PROGRESS_SECONDS`),
//! for logs of runs under `nohup` or CI. Nothing unless [`show_on_stderr`] was called: the
//! server's stderr carries its logs, and its jobs report progress through the admin API.

use indicatif::{ProgressBar, ProgressStyle};
use reflectance_core::util::progress::Observer;
use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Shortest time between two plain progress lines, unless `REFLECTANCE_PROGRESS_SECONDS`
/// (a non-negative number of seconds) says otherwise.
pub const LINE_INTERVAL: Duration = Duration::from_secs(30);

fn line_interval() -> Duration {
    std::env::var("REFLECTANCE_PROGRESS_SECONDS")
        .ok()
        .and_then(|s| Duration::try_from_secs_f64(s.trim().parse().ok()?).ok())
        .unwrap_or(LINE_INTERVAL)
}

static SHOWN_ON_STDERR: AtomicBool = AtomicBool::new(false);

/// From now on, this process shows progress on stderr.
pub fn show_on_stderr() {
    SHOWN_ON_STDERR.store(true, Ordering::Relaxed);
}

/// Progress of one run of `len` steps, shown as the process's stderr allows.
pub struct Bar(Shown);

enum Shown {
    Terminal(ProgressBar),
    Lines(Lines),
    Hidden,
}

/// A bar of `len` steps labelled `what`.
pub fn bar(len: u64, what: &str) -> Bar {
    if !SHOWN_ON_STDERR.load(Ordering::Relaxed) {
        Bar(Shown::Hidden)
    } else if std::io::stderr().is_terminal() {
        let style = ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} ({eta} left)")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
        let bar = ProgressBar::new(len)
            .with_style(style)
            .with_message(what.to_string());
        Bar(Shown::Terminal(bar))
    } else {
        let sink = Box::new(std::io::stderr());
        Bar(Shown::Lines(Lines::new(what, len, line_interval(), sink)))
    }
}

/// `work` observed by a bar labelled `what`, which ends with it.
pub fn observed<T>(what: &str, work: impl FnOnce(&Bar) -> T) -> T {
    let bar = bar(0, what);
    let out = work(&bar);
    bar.finish();
    out
}

impl Bar {
    /// `n` more steps are done.
    pub fn inc(&self, n: u64) {
        match &self.0 {
            Shown::Terminal(bar) => bar.inc(n),
            Shown::Lines(lines) => lines.advance(n),
            Shown::Hidden => {}
        }
    }

    /// The run is over: the bar disappears; plain lines, if any were printed, end with one
    /// saying how long it took.
    pub fn finish(&self) {
        match &self.0 {
            Shown::Terminal(bar) => bar.finish_and_clear(),
            Shown::Lines(lines) => lines.finish(),
            Shown::Hidden => {}
        }
    }
}

/// A bar follows a run that reports to an [`Observer`]: each stage restarts it.
impl Observer for Bar {
    fn stage(&self, name: &'static str) {
        match &self.0 {
            Shown::Terminal(bar) => bar.set_message(name),
            Shown::Lines(lines) => lines.restart(name),
            Shown::Hidden => {}
        }
    }

    fn progress(&self, done: usize, total: usize) {
        match &self.0 {
            Shown::Terminal(bar) => {
                bar.set_length(total as u64);
                bar.set_position(done as u64);
            }
            Shown::Lines(lines) => {
                lines.len.store(total as u64, Ordering::Relaxed);
                lines.set(done as u64);
            }
            Shown::Hidden => {}
        }
    }
}

/// Plain progress lines, `what: done/len (p %), elapsed, ~left`, at most one per interval.
struct Lines {
    len: AtomicU64,
    done: AtomicU64,
    interval: Duration,
    state: Mutex<LineState>,
    sink: Mutex<Box<dyn Write + Send>>,
}

struct LineState {
    what: String,
    start: Instant,
    last: Instant,
    printed: bool,
}

impl Lines {
    fn new(what: &str, len: u64, interval: Duration, sink: Box<dyn Write + Send>) -> Lines {
        let now = Instant::now();
        Lines {
            len: AtomicU64::new(len),
            done: AtomicU64::new(0),
            interval,
            state: Mutex::new(LineState {
                what: what.to_string(),
                start: now,
                last: now,
                printed: false,
            }),
            sink: Mutex::new(sink),
        }
    }

    fn advance(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        self.maybe_print(done);
    }

    /// Reports from parallel workers may arrive out of order: the count never goes back.
    fn set(&self, done: u64) {
        let done = self.done.fetch_max(done, Ordering::Relaxed).max(done);
        self.maybe_print(done);
    }

    fn restart(&self, what: &str) {
        self.done.store(0, Ordering::Relaxed);
        if let Ok(mut state) = self.state.lock() {
            state.what = what.to_string();
            state.start = Instant::now();
        }
    }

    fn maybe_print(&self, done: u64) {
        // A thread that finds the lock taken skips its line: another is printing one.
        let Ok(mut state) = self.state.try_lock() else {
            return;
        };
        if state.last.elapsed() < self.interval {
            return;
        }
        let len = self.len.load(Ordering::Relaxed);
        let elapsed = state.start.elapsed();
        let mut line = format!("{}: {done}/{len}", state.what);
        if len > 0 {
            let share = done.min(len) as f64 / len as f64;
            line += &format!(" ({:.0} %), {} elapsed", 100.0 * share, clock(elapsed));
            if share > 0.0 {
                let left = elapsed.as_secs_f64() * (1.0 - share) / share;
                line += &format!(", ~{} left", clock(Duration::from_secs_f64(left)));
            }
        }
        self.write(&line);
        state.last = Instant::now();
        state.printed = true;
    }

    fn finish(&self) {
        let Ok(state) = self.state.lock() else {
            return;
        };
        if state.printed {
            let done = self.done.load(Ordering::Relaxed);
            let line = format!(
                "{}: {done} done in {}",
                state.what,
                clock(state.start.elapsed())
            );
            self.write(&line);
        }
    }

    fn write(&self, line: &str) {
        if let Ok(mut sink) = self.sink.lock() {
            // Progress is best effort: a closed stderr must not fail the run.
            let _ = writeln!(sink, "{line}");
        }
    }
}

/// `1h02m03s`, `4m05s`, `6s`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    match (s / 3600, s / 60 % 60, s % 60) {
        (0, 0, sec) => format!("{sec}s"),
        (0, min, sec) => format!("{min}m{sec:02}s"),
        (h, min, sec) => format!("{h}h{min:02}m{sec:02}s"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// A sink whose text the test reads back.
    #[derive(Clone, Default)]
    struct Captured(Arc<Mutex<Vec<u8>>>);

    impl Write for Captured {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(bytes);
            Ok(bytes.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Captured {
        fn lines(&self) -> Vec<String> {
            let text = String::from_utf8(self.0.lock().unwrap().clone()).unwrap();
            text.lines().map(str::to_string).collect()
        }
    }

    fn lines(what: &str, len: u64, interval: Duration) -> (Bar, Captured) {
        let sink = Captured::default();
        let lines = Lines::new(what, len, interval, Box::new(sink.clone()));
        (Bar(Shown::Lines(lines)), sink)
    }

    #[test]
    fn lines_report_position_share_and_end() {
        let (bar, sink) = lines("render", 4, Duration::ZERO);
        bar.inc(1);
        bar.inc(3);
        bar.finish();
        let printed = sink.lines();
        assert_eq!(printed.len(), 3, "{printed:?}");
        // Times as "3s" or "1m05s", whatever a loaded machine took.
        let time_then = |line: &str, before: &str, after: &str| {
            let time = line
                .strip_prefix(before)
                .and_then(|rest| rest.strip_suffix(after));
            time.is_some_and(|t| {
                t.ends_with('s')
                    && t[..t.len() - 1]
                        .chars()
                        .all(|c| c.is_ascii_digit() || c == 'm')
            })
        };
        let first = printed[0].split(", ~").next().unwrap_or_default();
        assert!(
            time_then(first, "render: 1/4 (25 %), ", " elapsed"),
            "{printed:?}"
        );
        assert!(printed[1].starts_with("render: 4/4 (100 %)"), "{printed:?}");
        assert!(
            time_then(&printed[2], "render: 4 done in ", ""),
            "{printed:?}"
        );
    }

    #[test]
    fn short_runs_print_nothing() {
        let (bar, sink) = lines("features", 3, Duration::from_secs(3600));
        for _ in 0..3 {
            bar.inc(1);
        }
        bar.finish();
        assert!(sink.lines().is_empty());
    }

    #[test]
    fn observed_stages_restart_the_count() {
        let (bar, sink) = lines("train", 1, Duration::ZERO);
        bar.stage("fit");
        bar.progress(1, 1);
        bar.stage("cross_validate");
        bar.progress(0, 70);
        bar.progress(35, 70);
        let printed = sink.lines();
        assert!(printed[0].starts_with("fit: 1/1 (100 %)"), "{printed:?}");
        assert!(
            printed[1].starts_with("cross_validate: 0/70 (0 %)"),
            "{printed:?}"
        );
        assert!(
            !printed[1].contains("left"),
            "no estimate from nothing: {printed:?}"
        );
        assert!(
            printed[2].starts_with("cross_validate: 35/70 (50 %)"),
            "{printed:?}"
        );
    }

    #[test]
    fn clock_reads_like_a_clock() {
        assert_eq!(clock(Duration::from_secs(6)), "6s");
        assert_eq!(clock(Duration::from_secs(245)), "4m05s");
        assert_eq!(clock(Duration::from_secs(3723)), "1h02m03s");
    }
}
