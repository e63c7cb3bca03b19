//! Progress drawn as bars on the terminal's stderr (hidden when it is not a terminal): the
//! command line's side of [`crate::progress::Progress`].

use crate::progress::Progress;
use indicatif::{ProgressBar, ProgressStyle};
use std::sync::{Mutex, PoisonError};

/// A progress bar for `len` steps of `unit`.
pub fn progress(len: usize, unit: &str, message: String) -> ProgressBar {
    let template =
        format!("{{msg}} [{{bar:40}}] {{pos}}/{{len}} {unit} ({{per_sec}}, {{eta}} left)");
    let bar = ProgressBar::new(len as u64).with_style(
        ProgressStyle::with_template(&template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(message);
    bar
}

/// A spinner with a message, for work of unknown length (e.g. a stream).
pub fn spinner(message: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} {prefix}: {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_prefix(message.to_string());
    bar
}

/// Each stage of the library's work as a bar (a spinner when its length is unknown).
pub struct Bars {
    bar: Mutex<Option<ProgressBar>>,
    /// Finished bars stay on the terminal (otherwise they are cleared).
    keep: bool,
}

impl Bars {
    /// Bars cleared as their stage finishes.
    pub fn new() -> Self {
        Self {
            bar: Mutex::new(None),
            keep: false,
        }
    }

    /// Bars left on the terminal once finished, as a record of the stages.
    pub fn kept() -> Self {
        Self {
            keep: true,
            ..Self::new()
        }
    }

    /// The current bar, if a stage has started.
    fn current(&self) -> Option<ProgressBar> {
        // A bar is a handle: cloned out so no lock is held while it draws.
        self.bar
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

impl Default for Bars {
    fn default() -> Self {
        Self::new()
    }
}

impl Progress for Bars {
    fn start(&self, stage: &str, total: Option<u64>, unit: &str) {
        let bar = match total {
            Some(n) => progress(n as usize, unit, stage.to_string()),
            None => spinner(stage),
        };
        *self.bar.lock().unwrap_or_else(PoisonError::into_inner) = Some(bar);
    }

    fn advance_to(&self, done: u64) {
        if let Some(bar) = self.current() {
            bar.set_position(done);
            // A spinner shows no position: it turns instead.
            if bar.length().is_none() {
                bar.tick();
            }
        }
    }

    fn message(&self, text: &str) {
        if let Some(bar) = self.current() {
            bar.set_message(text.to_string());
        }
    }

    fn note(&self, line: &str) {
        // Above the bar; dropped, as the bar is, when stderr is not a terminal.
        if let Some(bar) = self.current() {
            bar.println(line);
        }
    }

    fn finish(&self) {
        if let Some(bar) = self.current() {
            if self.keep {
                bar.finish();
            } else {
                bar.finish_and_clear();
            }
        }
    }
}
