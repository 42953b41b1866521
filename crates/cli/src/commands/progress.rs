//! The pipeline's progress on the terminal: indicatif bars and the step log on stderr.
//!
//! [`Bars`] is the command line's [`Progress`]: each task of the pipeline is a bar of a
//! shared [`MultiProgress`] (several projects run side by side, each line and bar prefixed
//! with its project), each log line is printed above the bars, or straight to stderr when
//! the bars are hidden (no terminal).

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use pingcal_pipeline::{Progress, Reporter, Task};

/// Bars and lines of one project on a shared [`MultiProgress`].
pub struct Bars {
    multi: MultiProgress,
    prefix: String,
}

impl Bars {
    /// Draws on `multi`, every line and bar starting with `prefix`.
    pub fn new(multi: MultiProgress, prefix: impl Into<String>) -> Self {
        Self {
            multi,
            prefix: prefix.into(),
        }
    }
}

struct Bar(ProgressBar);

impl Task for Bar {
    fn advance(&self, n: u64) {
        self.0.inc(n);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl Progress for Bars {
    fn line(&self, line: &str) {
        if self.multi.is_hidden() {
            eprintln!("{}{line}", self.prefix);
        } else {
            let _ = self.multi.println(format!("{}{line}", self.prefix));
        }
    }

    fn task(&self, what: &str, len: u64) -> Box<dyn Task> {
        let pb = self.multi.add(ProgressBar::new(len));
        pb.set_style(
            ProgressStyle::with_template(
                "{prefix}{msg:<24} [{bar:30}] {pos}/{len} {elapsed_precise}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        pb.set_prefix(self.prefix.clone());
        pb.set_message(what.to_string());
        Box::new(Bar(pb))
    }
}

/// A reporter drawing on `multi` (None: silent).
pub fn reporter(multi: Option<&MultiProgress>, prefix: impl Into<String>) -> Reporter {
    match multi {
        Some(m) => Reporter::new(Box::new(Bars::new(m.clone(), prefix))),
        None => Reporter::silent(),
    }
}

/// The step log of a quiet run: only its warnings, each on stderr as it comes (`--quiet`
/// hides the progress, never a warning).
struct WarningsOnly {
    prefix: String,
}

struct NoBar;

impl Task for NoBar {
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

impl Progress for WarningsOnly {
    fn line(&self, line: &str) {
        if line.starts_with("warning: ") {
            eprintln!("pingcal: {}{line}", self.prefix);
        }
    }

    fn task(&self, _: &str, _: u64) -> Box<dyn Task> {
        Box::new(NoBar)
    }
}

/// A reporter for a quiet run: no bars, no log, but every warning on stderr.
pub fn quiet_reporter(prefix: impl Into<String>) -> Reporter {
    Reporter::new(Box::new(WarningsOnly {
        prefix: prefix.into(),
    }))
}
