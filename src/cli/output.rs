//! What every command shares in how it talks to the user: progress bars on stderr (drawn
//! only when stderr is a terminal), summaries on stderr, and `--json` summaries as one line
//! of JSON on stdout.

use indicatif::{ProgressBar, ProgressStyle};
use mesobake_core::observer::BakeObserver;
use std::io::IsTerminal;

/// A progress bar on stderr, drawn only when stderr is a terminal.
pub struct Progress(ProgressBar);

impl Progress {
    /// A bar labelled `what`.
    pub fn new(what: &str) -> Self {
        let bar = if std::io::stderr().is_terminal() {
            ProgressBar::new(1)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ({eta})")
                .expect("static template")
                .progress_chars("=> "),
        );
        bar.set_message(what.to_string());
        Progress(bar)
    }

    /// Sets the bar to `done` of `total`.
    pub fn set(&self, done: u64, total: u64) {
        self.0.set_length(total);
        self.0.set_position(done);
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl BakeObserver for Progress {
    fn progress(&self, done: u64, total: u64) {
        self.set(done, total);
    }

    /// Relabels the bar with the stage's name and starts it over.
    fn stage(&self, name: &str) {
        self.0.set_message(name.replace('_', " "));
        self.0.set_position(0);
    }
}

/// Prints a `--json` summary: one line on stdout.
pub fn print_json(summary: &serde_json::Value) {
    println!("{summary}");
}
