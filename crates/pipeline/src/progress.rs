//! How the pipeline tells what it is doing, without drawing anything itself.
//!
//! The steps log one line per result and open a [`Task`] for work that takes a while. The
//! [`Reporter`] keeps the lines (they become the step log of the report) and hands both to
//! a [`Progress`], which the caller provides: the command line draws progress bars
//! (`commands::progress`), tests and batch runs use [`Reporter::silent`].

use std::sync::Mutex;

/// Where the pipeline's progress goes.
pub trait Progress: Send + Sync {
    /// One line of the step log.
    fn line(&self, line: &str);
    /// Starts a task of `len` steps described by `what`.
    fn task(&self, what: &str, len: u64) -> Box<dyn Task>;
}

/// A task under way: steps are counted from any thread.
pub trait Task: Send + Sync {
    /// `n` more steps are done.
    fn advance(&self, n: u64);
    /// The task is over (it is no longer shown).
    fn finish(&self);
}

/// The step log of one project, and where its progress is shown.
pub struct Reporter {
    progress: Option<Box<dyn Progress>>,
    lines: Mutex<Vec<String>>,
}

struct NoTask;

impl Task for NoTask {
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

impl Reporter {
    /// A reporter that shows its progress on `progress`.
    pub fn new(progress: Box<dyn Progress>) -> Self {
        Self {
            progress: Some(progress),
            lines: Mutex::new(Vec::new()),
        }
    }

    /// A reporter that only keeps the lines (tests, batch with --quiet).
    pub fn silent() -> Self {
        Self {
            progress: None,
            lines: Mutex::new(Vec::new()),
        }
    }

    /// Logs one line.
    pub fn log(&self, line: impl Into<String>) {
        let line = line.into();
        if let Some(p) = &self.progress {
            p.line(&line);
        }
        self.lines.lock().expect("log lock").push(line);
    }

    /// Starts a task of `len` steps (shown nowhere when silent).
    pub fn task(&self, what: &str, len: u64) -> Box<dyn Task> {
        match &self.progress {
            Some(p) => p.task(what, len),
            None => Box::new(NoTask),
        }
    }

    /// The lines logged so far.
    pub fn lines(&self) -> Vec<String> {
        self.lines.lock().expect("log lock").clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Arc;

    #[derive(Default)]
    struct Record {
        lines: Mutex<Vec<String>>,
        steps: Arc<AtomicU64>,
    }

    struct Count(Arc<AtomicU64>);

    impl Task for Count {
        fn advance(&self, n: u64) {
            self.0.fetch_add(n, Ordering::Relaxed);
        }
        fn finish(&self) {}
    }

    impl Progress for Arc<Record> {
        fn line(&self, line: &str) {
            self.lines.lock().unwrap().push(line.to_string());
        }
        fn task(&self, _: &str, _: u64) -> Box<dyn Task> {
            Box::new(Count(self.steps.clone()))
        }
    }

    #[test]
    fn lines_are_kept_and_shown() {
        let rec = Arc::new(Record::default());
        let rep = Reporter::new(Box::new(rec.clone()));
        rep.log("one");
        let t = rep.task("work", 3);
        t.advance(1);
        t.advance(2);
        t.finish();
        rep.log("two");
        assert_eq!(rep.lines(), vec!["one", "two"]);
        assert_eq!(*rec.lines.lock().unwrap(), vec!["one", "two"]);
        assert_eq!(rec.steps.load(Ordering::Relaxed), 3);
    }

    #[test]
    fn a_silent_reporter_keeps_the_lines() {
        let rep = Reporter::silent();
        rep.log("only kept");
        rep.task("nothing shown", 5).advance(5);
        assert_eq!(rep.lines(), vec!["only kept"]);
    }
}
