//! How long work reports its progress, without deciding how it is shown.
//!
//! The library calls a [`Progress`]; the command line draws it as bars on the terminal,
//! another program may log it, forward it, or ignore it with [`Silent`]. Work is a
//! sequence of stages: each is started, advanced, maybe described, and finished.

/// Receives the progress of long work. Object-safe and shareable between threads, so it
/// can be passed as `&dyn Progress` to work that runs in parallel.
pub trait Progress: Send + Sync {
    /// A stage begins: `stage` says what it does (e.g. "aligning"), `total` is how many
    /// `unit`s it has (e.g. 40 "frames"), none when that is not known in advance.
    fn start(&self, stage: &str, total: Option<u64>, unit: &str);
    /// `done` units of the current stage are done (counted from its start).
    fn advance_to(&self, done: u64);
    /// What the current stage is doing now (e.g. a rate, a loss); replaces the last.
    fn message(&self, text: &str);
    /// A line worth keeping, beside the progress (e.g. a message refused).
    fn note(&self, line: &str);
    /// The current stage is over.
    fn finish(&self);
}

/// Progress nobody watches.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _: &str, _: Option<u64>, _: &str) {}
    fn advance_to(&self, _: u64) {}
    fn message(&self, _: &str) {}
    fn note(&self, _: &str) {}
    fn finish(&self) {}
}
