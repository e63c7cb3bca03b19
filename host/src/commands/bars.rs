//! Progress on the command line, the command line's side of [`rollfuse::progress::Progress`]:
//! a bar on a terminal; elsewhere (a log, a pipe, a service) a plain line every so often
//! while a stage runs, and one when a stage that printed any ends.

use indicatif::{ProgressBar, ProgressStyle};
use rollfuse::progress::Progress;
use std::io::{IsTerminal, Write};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// How progress is shown (`--progress`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Mode {
    /// A bar when stderr is a terminal, plain lines when it is not.
    #[default]
    Auto,
    /// Always a bar (drawn only on a terminal).
    Bar,
    /// Always plain lines.
    Plain,
    /// Nothing but the lines worth keeping (notes).
    None,
}

/// The command line's progress settings (`--progress`, `--progress-every`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Show {
    /// Bar, lines or nothing.
    pub mode: Mode,
    /// Plain lines: at most one this often while a stage runs.
    pub every: Duration,
}

impl Show {
    /// The default: `auto`, a line every 10 s.
    pub const DEFAULT: Show = Show {
        mode: Mode::Auto,
        every: Duration::from_secs(10),
    };
}

impl Default for Show {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// A progress bar for `len` steps of `unit`; messages follow it.
fn progress(len: u64, unit: &str, stage: &str) -> ProgressBar {
    let template = format!(
        "{{prefix}} [{{bar:40}}] {{pos}}/{{len}} {unit} ({{per_sec}}, {{eta}} left) {{msg}}"
    );
    let bar = ProgressBar::new(len).with_style(
        ProgressStyle::with_template(&template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_prefix(stage.to_string());
    bar
}

/// A spinner with a message, for work of unknown length (e.g. a stream).
fn spinner(message: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} {prefix}: {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_prefix(message.to_string());
    bar
}

/// Each stage of the library's work shown as [`Show`] says.
pub struct Bars {
    shown: Shown,
}

enum Shown {
    Bar {
        bar: Mutex<Option<ProgressBar>>,
        /// Finished bars stay on the terminal (otherwise they are cleared).
        keep: bool,
    },
    Lines(Mutex<Lines>),
    Hidden,
}

impl Bars {
    /// Progress as `show` says, bars cleared as their stage finishes.
    pub fn new(show: Show) -> Self {
        let bar = || Shown::Bar {
            bar: Mutex::new(None),
            keep: false,
        };
        let lines = || {
            Shown::Lines(Mutex::new(Lines::new(
                show.every,
                Box::new(std::io::stderr()),
            )))
        };
        let shown = match show.mode {
            Mode::Auto if std::io::stderr().is_terminal() => bar(),
            Mode::Auto | Mode::Plain => lines(),
            Mode::Bar => bar(),
            Mode::None => Shown::Hidden,
        };
        Self { shown }
    }

    /// Progress as `show` says, finished bars left on the terminal as a record of the
    /// stages.
    pub fn kept(show: Show) -> Self {
        let mut bars = Self::new(show);
        if let Shown::Bar { keep, .. } = &mut bars.shown {
            *keep = true;
        }
        bars
    }

    /// The current bar, if bars are shown and a stage has started.
    fn bar(&self) -> Option<ProgressBar> {
        match &self.shown {
            // A bar is a handle: cloned out so no lock is held while it draws.
            Shown::Bar { bar, .. } => bar.lock().unwrap_or_else(PoisonError::into_inner).clone(),
            _ => None,
        }
    }

    /// Runs `f` on the plain lines, if they are shown.
    fn lines(&self, f: impl FnOnce(&mut Lines)) {
        if let Shown::Lines(lines) = &self.shown {
            f(&mut lines.lock().unwrap_or_else(PoisonError::into_inner));
        }
    }
}

impl Progress for Bars {
    fn start(&self, stage: &str, total: Option<u64>, unit: &str) {
        if let Shown::Bar { bar, .. } = &self.shown {
            let new = match total {
                Some(n) => progress(n, unit, stage),
                None => spinner(stage),
            };
            *bar.lock().unwrap_or_else(PoisonError::into_inner) = Some(new);
        }
        self.lines(|l| l.start(stage, total, unit, Instant::now()));
    }

    fn advance_to(&self, done: u64) {
        if let Some(bar) = self.bar() {
            bar.set_position(done);
            // A spinner shows no position: it turns instead.
            if bar.length().is_none() {
                bar.tick();
            }
        }
        self.lines(|l| l.advance_to(done, Instant::now()));
    }

    fn message(&self, text: &str) {
        if let Some(bar) = self.bar() {
            bar.set_message(text.to_string());
        }
        self.lines(|l| l.message(text));
    }

    fn note(&self, line: &str) {
        match self.bar() {
            // Above the bar (indicatif drops it, as the bar, when stderr is no terminal).
            Some(bar) if !bar.is_hidden() => bar.println(line),
            _ => eprintln!("{line}"),
        }
    }

    fn finish(&self) {
        if let Shown::Bar { keep, .. } = &self.shown
            && let Some(bar) = self.bar()
        {
            if *keep {
                bar.finish();
            } else {
                bar.finish_and_clear();
            }
        }
        self.lines(|l| l.finish(Instant::now()));
    }
}

/// Plain progress lines: a stage says nothing for its first `every`, then a line at most
/// every `every`, and a closing line if it said anything. Quick work prints nothing.
struct Lines {
    every: Duration,
    out: Box<dyn Write + Send>,
    stage: Option<Stage>,
}

/// The stage plain lines are about.
struct Stage {
    name: String,
    total: Option<u64>,
    unit: String,
    started: Instant,
    /// When the last line was printed (the start until one is).
    said: Instant,
    printed: bool,
    done: u64,
    message: String,
}

impl Lines {
    fn new(every: Duration, out: Box<dyn Write + Send>) -> Self {
        Self {
            every,
            out,
            stage: None,
        }
    }

    fn start(&mut self, name: &str, total: Option<u64>, unit: &str, now: Instant) {
        self.stage = Some(Stage {
            name: name.to_string(),
            total,
            unit: unit.to_string(),
            started: now,
            said: now,
            printed: false,
            done: 0,
            message: String::new(),
        });
    }

    fn advance_to(&mut self, done: u64, now: Instant) {
        let every = self.every;
        let Some(stage) = self.stage.as_mut() else {
            return;
        };
        stage.done = done;
        if now.duration_since(stage.said) >= every {
            stage.said = now;
            stage.printed = true;
            let line = stage.line(now);
            // Progress is advice: a closed stderr must not stop the work.
            let _ = writeln!(self.out, "{line}");
        }
    }

    fn message(&mut self, text: &str) {
        if let Some(stage) = self.stage.as_mut() {
            stage.message = text.to_string();
        }
    }

    fn finish(&mut self, now: Instant) {
        if let Some(stage) = self.stage.take()
            && stage.printed
        {
            let line = format!(
                "{}: done, {} {} in {}",
                stage.name,
                stage.done,
                stage.unit,
                clock(now.duration_since(stage.started))
            );
            let _ = writeln!(self.out, "{line}");
        }
    }
}

impl Stage {
    /// `training: 120/2000 steps (6 %), loss 0.413, 40 s`; without a total the message
    /// alone when there is one (it counts), as `receiving tiles: 96 tiles, 30 tiles/s, 3 s`.
    fn line(&self, now: Instant) -> String {
        let count = match self.total {
            Some(total) => {
                let percent = 100 * self.done / total.max(1);
                Some(format!("{}/{total} {} ({percent} %)", self.done, self.unit))
            }
            None if self.message.is_empty() => Some(format!("{} {}", self.done, self.unit)),
            None => None,
        };
        let message = Some(self.message.clone()).filter(|m| !m.is_empty());
        let elapsed = Some(clock(now.duration_since(self.started)));
        let parts: Vec<String> = [count, message, elapsed].into_iter().flatten().collect();
        format!("{}: {}", self.name, parts.join(", "))
    }
}

/// `42 s`, `17 min 3 s`, `2 h 5 min`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {} s", s / 60, s % 60),
        _ => format!("{} h {} min", s / 3600, s % 3600 / 60),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// A sink the test can read back.
    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);

    impl Write for Shared {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Shared {
        fn text(&self) -> String {
            String::from_utf8(self.0.lock().unwrap().clone()).unwrap()
        }
    }

    #[test]
    fn quick_work_prints_nothing_and_long_work_a_line_every_so_often() {
        let out = Shared::default();
        let mut lines = Lines::new(Duration::from_secs(10), Box::new(out.clone()));
        let t0 = Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        lines.start("quick", Some(10), "frames", t0);
        lines.advance_to(10, at(9));
        lines.finish(at(9));
        assert_eq!(out.text(), "", "under 10 s: nothing");

        lines.start("training", Some(2000), "steps", at(100));
        lines.message("loss 0.41");
        for (step, s) in [(100, 105), (300, 111), (400, 115), (600, 121), (700, 130)] {
            lines.advance_to(step, at(s));
        }
        lines.finish(at(3800));
        assert_eq!(
            out.text(),
            "training: 300/2000 steps (15 %), loss 0.41, 11 s\n\
             training: 600/2000 steps (30 %), loss 0.41, 21 s\n\
             training: done, 700 steps in 1 h 1 min\n"
        );
    }

    #[test]
    fn work_of_unknown_length_counts_without_a_total() {
        let out = Shared::default();
        let mut lines = Lines::new(Duration::ZERO, Box::new(out.clone()));
        let t0 = Instant::now();
        lines.start("streaming", None, "tiles", t0);
        lines.advance_to(75, t0 + Duration::from_secs(90));
        lines.message("96 tiles, 30 tiles/s");
        lines.advance_to(96, t0 + Duration::from_secs(91));
        assert_eq!(
            out.text(),
            "streaming: 75 tiles, 1 min 30 s\nstreaming: 96 tiles, 30 tiles/s, 1 min 31 s\n"
        );
    }
}
