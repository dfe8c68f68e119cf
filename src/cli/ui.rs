//! Terminal output: stage progress (spinners on stderr, hidden when stderr is
//! not a terminal or with `-q`), timings, and aligned summary tables.

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Verbosity and progress display.
pub struct Ui {
    pub verbose: u8,
    pub quiet: bool,
}

/// A running stage: a spinner with a message, and its start time.
pub struct Stage {
    bar: ProgressBar,
    start: Instant,
}

impl Stage {
    /// Stops the spinner and returns how long the stage took.
    pub fn done(self) -> Duration {
        self.bar.finish_and_clear();
        self.start.elapsed()
    }
}

impl Ui {
    pub fn new(verbose: u8, quiet: bool) -> Self {
        Ui { verbose, quiet }
    }

    /// Starts a stage with a spinner showing `what`.
    pub fn stage(&self, what: &str) -> Stage {
        let target = if self.quiet {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        };
        let bar = ProgressBar::with_draw_target(None, target);
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid template"),
        );
        bar.set_message(what.to_string());
        // (a spinner nobody sees needs no thread of its own: one thread
        // fewer that a tight limit could refuse)
        if !bar.is_hidden() {
            bar.enable_steady_tick(Duration::from_millis(100));
        }
        Stage {
            bar,
            start: Instant::now(),
        }
    }

    /// Prints a line unless quiet.
    pub fn say(&self, line: impl AsRef<str>) {
        if !self.quiet {
            println!("{}", line.as_ref());
        }
    }

    /// Prints a warning to stderr (even when quiet: it may change the result).
    pub fn warn(&self, line: impl AsRef<str>) {
        eprintln!("warning: {}", line.as_ref());
    }
}

/// Seconds with 3 decimals.
pub fn secs(d: Duration) -> String {
    format!("{:.3} s", d.as_secs_f64())
}

/// An integer with thousands separators.
pub fn count(n: impl Into<u64>) -> String {
    let s = n.into().to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Formats rows as an aligned table (first column left, others right).
pub fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let cols = header.len();
    let mut width: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate().take(cols) {
            width[i] = width[i].max(c.chars().count());
        }
    }
    // numeric-looking columns align right, text columns left
    let numeric: Vec<bool> = (0..cols)
        .map(|i| {
            i > 0
                && rows.iter().all(|r| {
                    r.get(i).is_none_or(|c| {
                        c.is_empty() || c.starts_with(|ch: char| ch.is_ascii_digit() || ch == '-')
                    })
                })
        })
        .collect();
    let line = |cells: Vec<String>| -> String {
        let mut s = String::from("  ");
        for (i, c) in cells.iter().enumerate() {
            let pad = width[i] - c.chars().count();
            if !numeric[i] {
                if i > 0 {
                    s.push_str("  ");
                }
                s.push_str(c);
                s.push_str(&" ".repeat(pad));
            } else {
                s.push_str("  ");
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            }
        }
        s.trim_end().to_string()
    };
    let mut out = line(header.iter().map(|h| h.to_string()).collect());
    for r in rows {
        out.push('\n');
        out.push_str(&line(r.clone()));
    }
    out
}
