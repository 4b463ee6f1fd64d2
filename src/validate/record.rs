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
    /// Largest |ETOTAL − ETOTAL₀| / (largest energy term so far) over the run.
    max_balance_error: f64,
    /// Running maximum of the largest energy term (J).
    scale: f64,
}

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
            max_balance_error: 0.0,
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
            self.max_balance_error = self.max_balance_error.max(drift / self.scale);
        }
        if let Some((out, _)) = self.output.as_mut() {
            out.after_step(solver, last)?;
        }
        Ok(())
    }

    /// Closes the results file (and draws `energy.png`) and records the balance drift
    /// (`energy_balance_error`) and, when recording, the results path (`results_h5`) in
    /// the outcome's details.
    pub fn finish(
        self,
        solver: &Solver,
        details: &mut serde_json::Map<String, serde_json::Value>,
    ) -> Result<()> {
        details.insert("energy_balance_error".into(), json!(self.max_balance_error));
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
