//! Progress bars for long work, on the terminal's stderr (hidden when it is not a terminal).

use indicatif::{ProgressBar, ProgressStyle};

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
pub fn progress_spinner(message: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} {prefix}: {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_prefix(message.to_string());
    bar
}
