//! When a run writes checkpoints (every N steps and/or every T seconds of wall time), and
//! how a run restarts from one: the checkpoint's scene must be the scene given, its rank
//! count the job's; every rank reads its own state and continues from it (grains on the
//! ranks that owned them, halo begun afresh), bitwise as if it had never stopped.

use crate::domain::Domain;
use crate::error::{InputError, MufeError, Result};
use crate::io::checkpoint::{read_checkpoint, write_checkpoint, CheckpointInfo};
use crate::scene::LoadedScene;
use crate::solver::{Solver, State};
use std::path::Path;
use std::time::Instant;

/// The checkpoint schedule of a run.
pub struct CheckpointSchedule {
    every_steps: Option<u64>,
    every_seconds: Option<f64>,
    keep: usize,
    last: Instant,
}

impl CheckpointSchedule {
    /// From the scene's `[output]` and the command line's `--checkpoint-every` (which
    /// replaces the scene's step interval).
    pub fn new(loaded: &LoadedScene, every_steps: Option<u64>) -> Self {
        let o = &loaded.scene.output;
        Self {
            every_steps: every_steps.or(o.checkpoint_every),
            every_seconds: o.checkpoint_interval,
            keep: o.checkpoints_kept,
            last: Instant::now(),
        }
    }

    /// After step `step`: writes a checkpoint when one is due. All ranks must call; the
    /// wall-time decision is reduced over ranks (clocks differ).
    pub fn after_step(
        &mut self,
        domain: &Domain,
        dir: &Path,
        loaded: &LoadedScene,
        solver: &Solver,
    ) -> Result<()> {
        let step = solver.state.step;
        let by_steps = self.every_steps.is_some_and(|n| step.is_multiple_of(n));
        let by_time = match self.every_seconds {
            Some(t) => {
                let mut elapsed = [self.last.elapsed().as_secs_f64()];
                domain.max_in_place(&mut elapsed);
                elapsed[0] >= t
            }
            None => false,
        };
        if !(by_steps || by_time) {
            return Ok(());
        }
        let bytes = serde_json::to_vec(&solver.state)
            .map_err(|e| MufeError::Run(format!("serialising the state for a checkpoint: {e}")))?;
        write_checkpoint(
            domain,
            dir,
            &loaded.text,
            &bytes,
            step,
            solver.state.time,
            self.keep,
        )?;
        self.last = Instant::now();
        Ok(())
    }
}

/// A checkpoint to continue from.
pub struct Restart {
    pub info: CheckpointInfo,
    pub state: State,
}

/// Reads this rank's state from the checkpoint at `path` for the scene `loaded`.
pub fn load_restart(domain: &Domain, loaded: &LoadedScene, path: &Path) -> Result<Restart> {
    let (info, bytes) = read_checkpoint(domain, path)?;
    if info.scene != loaded.text {
        return Err(InputError::new(
            path.display().to_string(),
            "scene",
            format!(
                "the checkpoint was written for another scene (or other --set values) than {}; restart with the scene and settings it was written with",
                loaded.path
            ),
        )
        .into());
    }
    let state: State = serde_json::from_slice(&bytes).map_err(|e| {
        InputError::new(
            path.display().to_string(),
            "state",
            format!("unreadable: {e}"),
        )
    })?;
    Ok(Restart { info, state })
}
