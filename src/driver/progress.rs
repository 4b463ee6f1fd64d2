//! Progress reporting: a live bar with ETA on a terminal, plain periodic log lines
//! otherwise (batch jobs, CI logs) and in a rank an MPI launcher started, whose terminal
//! may be the launcher's stand-in for a log file ([`crate::domain::launched_by_mpi_launcher`]).

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

pub struct Progress {
    enabled: bool,
    terminal: bool,
    start: Instant,
    last: Instant,
    last_fraction: f64,
    /// Fraction done at the first update since `start` (a restart starts part-way).
    start_fraction: f64,
    label: String,
}

impl Progress {
    /// `enabled` is false on non-root ranks and in quiet runs.
    pub fn new(enabled: bool, label: &str) -> Self {
        let now = Instant::now();
        Self {
            enabled,
            terminal: std::io::stdout().is_terminal() && !crate::domain::launched_by_mpi_launcher(),
            start: now,
            last: now,
            last_fraction: 0.0,
            start_fraction: f64::NAN,
            label: label.to_string(),
        }
    }

    /// Reports that `fraction` (0..1) of the run is done at simulated time `time` (s).
    /// When `waiting_on` gives a condition (a stage that ends on one, not on its cap), the
    /// time left is shown as the cap's ("cap in"), followed by how far the condition is;
    /// it is called only when a line is printed.
    pub fn update(
        &mut self,
        fraction: f64,
        step: u64,
        time: f64,
        waiting_on: impl FnOnce() -> Option<String>,
    ) {
        if !self.enabled {
            return;
        }
        let now = Instant::now();
        let since = now.duration_since(self.last);
        let elapsed = now.duration_since(self.start).as_secs_f64();
        if self.start_fraction.is_nan() {
            self.start_fraction = fraction;
        }
        let due = if self.terminal {
            since >= Duration::from_millis(200)
        } else {
            fraction - self.last_fraction >= 0.1 || since >= Duration::from_secs(30)
        };
        if !due {
            return;
        }
        let eta = format_secs(remaining_time(elapsed, self.start_fraction, fraction));
        let left = match waiting_on() {
            Some(condition) => format!("cap in {eta}  {condition}"),
            None => format!("ETA {eta}"),
        };
        if self.terminal {
            let width = 30;
            let filled = ((fraction * width as f64) as usize).min(width);
            // \x1b[K clears what a longer previous line left to the right
            print!(
                "\r{} [{}{}] {:5.1}%  t = {:.4e} s  step {}  elapsed {}  {}\x1b[K",
                self.label,
                "#".repeat(filled),
                "-".repeat(width - filled),
                100.0 * fraction,
                time,
                step,
                format_secs(elapsed),
                left
            );
            let _ = std::io::stdout().flush();
        } else {
            println!(
                "{}: {:5.1}% t = {:.4e} s step {} elapsed {} {}",
                self.label,
                100.0 * fraction,
                time,
                step,
                format_secs(elapsed),
                left
            );
            self.last_fraction = fraction;
        }
        self.last = now;
    }

    /// Renames the bar (e.g. at a new stage); the ETA restarts from there.
    pub fn set_label(&mut self, label: &str) {
        if self.label != label {
            self.label = label.to_string();
            self.start = Instant::now();
            self.last_fraction = 0.0;
            self.start_fraction = f64::NAN;
        }
    }

    /// Ends the live line.
    pub fn finish(&mut self) {
        if self.enabled && self.terminal {
            println!();
        }
    }
}

/// Time left (s) at the rate seen since `start_fraction`: `elapsed` for the fraction done
/// since then. NaN before any progress.
fn remaining_time(elapsed: f64, start_fraction: f64, fraction: f64) -> f64 {
    let done = fraction - start_fraction;
    if done > 0.0 {
        elapsed * (1.0 - fraction) / done
    } else {
        f64::NAN
    }
}

pub fn format_secs(s: f64) -> String {
    if !s.is_finite() {
        return "--".into();
    }
    if s < 60.0 {
        format!("{s:.1}s")
    } else if s < 3600.0 {
        format!("{}m{:02}s", (s / 60.0) as u64, (s % 60.0) as u64)
    } else {
        format!(
            "{}h{:02}m",
            (s / 3600.0) as u64,
            ((s % 3600.0) / 60.0) as u64
        )
    }
}

#[cfg(test)]
mod tests {
    use super::remaining_time;

    #[test]
    fn the_eta_counts_only_the_progress_made_since_this_process_started() {
        // fresh run: 10 % in 60 s → 540 s left
        assert!((remaining_time(60.0, 0.0, 0.1) - 540.0).abs() < 1e-9);
        // restarted at 33.5 %: 1 % more in 30 s → 65.5 % left takes 1965 s, not 60 s
        assert!((remaining_time(30.0, 0.335, 0.345) - 1965.0).abs() < 1e-6);
        assert!(remaining_time(5.0, 0.335, 0.335).is_nan());
    }
}
