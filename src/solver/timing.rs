//! Named, timed stages of the step pipeline; the table is printed at the end of a run.

use std::time::{Duration, Instant};

/// The stages of one explicit step, in pipeline order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Ghost exchange: packing the owned surface nodes, the transfer, unpacking the ghosts.
    Halo,
    /// The step's small collectives (rebuild decision, wall forces per grain, energy sums).
    /// Their payloads are small (at most one value per wall and grain: 96 kB for 2000
    /// grains), so their time is the wait for the slowest rank: a rank's compute stages
    /// show its own work only, and load imbalance (or a core that runs slower for a
    /// while) shows here.
    Sync,
    Contact,
    InternalForces,
    Boundary,
    Integrate,
    Energy,
    Output,
}

impl Stage {
    pub const ALL: [Stage; 8] = [
        Stage::Halo,
        Stage::Sync,
        Stage::Contact,
        Stage::InternalForces,
        Stage::Boundary,
        Stage::Integrate,
        Stage::Energy,
        Stage::Output,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Stage::Halo => "halo",
            Stage::Sync => "sync",
            Stage::Contact => "contact",
            Stage::InternalForces => "internal_forces",
            Stage::Boundary => "boundary",
            Stage::Integrate => "integrate",
            Stage::Energy => "energy",
            Stage::Output => "output",
        }
    }
}

/// Accumulated wall time per stage.
#[derive(Debug, Clone, Default)]
pub struct StageTimers {
    totals: [Duration; Stage::ALL.len()],
}

impl StageTimers {
    /// Runs `f` and charges its wall time to `stage`.
    #[inline]
    pub fn time<R>(&mut self, stage: Stage, f: impl FnOnce() -> R) -> R {
        let t0 = Instant::now();
        let r = f();
        self.totals[stage as usize] += t0.elapsed();
        r
    }

    /// Charges an externally measured duration to `stage`.
    pub fn add(&mut self, stage: Stage, d: Duration) {
        self.totals[stage as usize] += d;
    }

    pub fn seconds(&self, stage: Stage) -> f64 {
        self.totals[stage as usize].as_secs_f64()
    }

    pub fn total_seconds(&self) -> f64 {
        self.totals.iter().map(|d| d.as_secs_f64()).sum()
    }

    /// Share of step time spent in a stage (0..1).
    pub fn share(&self, stage: Stage) -> f64 {
        let t = self.total_seconds();
        if t > 0.0 {
            self.seconds(stage) / t
        } else {
            0.0
        }
    }

    /// The end-of-run table: stage, seconds, share, time per step.
    pub fn table(&self, steps: u64) -> String {
        let total = self.total_seconds();
        let mut s = format!(
            "{:<16} {:>10} {:>7} {:>12}\n",
            "stage", "wall s", "share", "µs/step"
        );
        for st in Stage::ALL {
            let t = self.seconds(st);
            s += &format!(
                "{:<16} {:>10.3} {:>6.1}% {:>12.2}\n",
                st.name(),
                t,
                if total > 0.0 { 100.0 * t / total } else { 0.0 },
                if steps > 0 {
                    1e6 * t / steps as f64
                } else {
                    0.0
                }
            );
        }
        s += &format!(
            "{:<16} {:>10.3} {:>6.1}% {:>12.2}\n",
            "total",
            total,
            100.0,
            if steps > 0 {
                1e6 * total / steps as f64
            } else {
                0.0
            }
        );
        s
    }
}
