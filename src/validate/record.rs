//! What every validation run keeps besides its curve: the largest energy-balance drift
//! over the run (each case must stay within [`BALANCE_TOLERANCE`]), and under
//! `mufe validate` the run's own `results.h5` (history with the whole energy ledger) and
//! `energy.png` in `DIR/<case>/mr_<MR>/`, written by the same output code as `mufe run`.
//! Tests run the cases without a recorder (no files).

use crate::domain::Domain;
use crate::driver::output::Output;
use crate::driver::RunOptions;
use crate::error::Result;
use crate::model::global::GlobalMesh;
use crate::scene::LoadedScene;
use crate::solver::Solver;
use serde_json::json;
use std::path::PathBuf;

/// Largest allowed drift of ETOTAL over a validation run, as a fraction of the largest
/// energy term seen up to then (docs/THEORY.md §9).
pub const BALANCE_TOLERANCE: f64 = 0.005;

/// Where `mufe validate` writes each run's results: `root/<case>/mr_<MR>/`.
pub struct Recorder<'d> {
    pub domain: &'d Domain,
    pub root: PathBuf,
}

impl Recorder<'_> {
    /// The directory of one run.
    pub fn run_dir(&self, case: &str, mr: f64) -> PathBuf {
        self.root.join(case).join(format!("mr_{mr:.4}"))
    }
}

/// The mesh layout a recorded run writes to `/mesh` (none without a recorder).
pub fn recorded_mesh(
    record: Option<&Recorder>,
    loaded: &LoadedScene,
) -> Result<Option<GlobalMesh>> {
    Ok(match record {
        Some(_) => Some(GlobalMesh::build(loaded)?),
        None => None,
    })
}

/// The output side of one validation run: the balance monitor, and the results file when
/// recording. Call [`Self::after_step`] after every step and [`Self::finish`] at the end.
pub struct CaseOutput<'a, 'd> {
    output: Option<(Output<'a, 'd>, PathBuf)>,
    /// Per decade of the running scale (⌊log₁₀ scale⌋): the largest drift / scale and the
    /// largest drift (J) seen while the scale was in that decade.
    drift_by_decade: std::collections::BTreeMap<i32, (f64, f64)>,
    /// Running maximum of the largest energy term (J).
    scale: f64,
}

/// Drifts smaller than this fraction of the run's largest energy term are round-off (the
/// ledger sums ~10⁵ element terms in the first steps, when every term is ~10⁻²⁹ J), not
/// an energy error.
const ROUND_OFF_FRACTION: f64 = 1e-9;

impl<'a, 'd> CaseOutput<'a, 'd> {
    /// Opens `results.h5` in the run's directory when recording (`mesh` from
    /// [`recorded_mesh`]).
    pub fn open(
        record: Option<&Recorder<'d>>,
        case: &str,
        mr: f64,
        loaded: &LoadedScene,
        mesh: Option<&'a GlobalMesh>,
        solver: &Solver,
    ) -> Result<Self> {
        let output = match (record, mesh) {
            (Some(r), Some(global)) => {
                let opts = RunOptions {
                    out: r.run_dir(case, mr),
                    threads: rayon::current_num_threads(),
                    max_steps: None,
                    quiet: true,
                    force: true,
                    checkpoint_every: None,
                    restart: None,
                    branch: false,
                };
                let out = Output::open(r.domain, loaded, &opts, global, solver, None)?;
                Some((out, opts.out))
            }
            _ => None,
        };
        Ok(Self {
            output,
            drift_by_decade: Default::default(),
            scale: 0.0,
        })
    }

    /// After each step: the balance drift, and the history row / frame the scene's
    /// `[output]` asks for. `last`: the run's final step.
    pub fn after_step(&mut self, solver: &Solver, last: bool) -> Result<()> {
        let e = &solver.state.energy;
        self.scale = self.scale.max(e.largest_term());
        if self.scale > 0.0 {
            let drift = (e.total() - e.initial_total.unwrap_or(0.0)).abs();
            let decade = self.scale.log10().floor() as i32;
            let worst = self.drift_by_decade.entry(decade).or_insert((0.0, 0.0));
            worst.0 = worst.0.max(drift / self.scale);
            worst.1 = worst.1.max(drift);
        }
        if let Some((out, _)) = self.output.as_mut() {
            out.after_step(solver, last)?;
        }
        Ok(())
    }

    /// Largest |ETOTAL − ETOTAL₀| / max(largest energy term so far, [`ROUND_OFF_FRACTION`]
    /// × the run's largest term) over the run (decades of the scale wholly below the floor
    /// count their largest drift over the floor: an upper bound).
    fn balance_error(&self) -> f64 {
        let floor = ROUND_OFF_FRACTION * self.scale;
        self.drift_by_decade
            .iter()
            .map(|(&decade, &(ratio, drift))| {
                if 10f64.powi(decade) >= floor {
                    ratio
                } else {
                    ratio.min(drift / floor)
                }
            })
            .fold(0.0, f64::max)
    }

    /// Closes the results file (and draws `energy.png`) and records the balance drift
    /// (`energy_balance_error`) and, when recording, the results path (`results_h5`) in
    /// the outcome's details.
    pub fn finish(
        self,
        solver: &Solver,
        details: &mut serde_json::Map<String, serde_json::Value>,
    ) -> Result<()> {
        details.insert("energy_balance_error".into(), json!(self.balance_error()));
        if let Some((out, dir)) = self.output {
            out.close(solver, false, false, &dir)?;
            details.insert(
                "results_h5".into(),
                json!(dir
                    .join(crate::io::results::RESULTS_FILE_NAME)
                    .display()
                    .to_string()),
            );
        }
        Ok(())
    }
}
