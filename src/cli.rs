//! Command-line interface (DESIGN.md §1). `main` only parses and dispatches here; every
//! error becomes one line on stderr and an exit code (2 for bad input).

use crate::domain::Domain;
use crate::error::{InputError, MufeError};
use crate::scene::{load_scene, LoadedScene};
use crate::solver::run::{build_solver, print_model_summary, run, RunOptions};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Parser)]
#[command(name = "mufe", version, about = "Micro finite-element (μFE) simulator for granular soil")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run a scene (serially, or under `mpirun -n K`) and write DIR/results.h5.
    Run {
        scene: PathBuf,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Threads per rank (default: all cores on one rank, 1 per rank under MPI).
        #[arg(long)]
        threads: Option<usize>,
        /// Override a scene field: --set materials.glass.youngs_modulus=2.1e11 (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Stop cleanly after N steps counted from t = 0.
        #[arg(long)]
        max_steps: Option<u64>,
        /// No progress output.
        #[arg(long)]
        quiet: bool,
    },
    /// Validate a scene without running: grains, elements, nodes, stable Δt, mass scaling, memory.
    Check {
        scene: PathBuf,
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
    },
}

/// Runs the CLI and returns the process exit code.
pub fn main_with_args(args: impl IntoIterator<Item = std::ffi::OsString>) -> i32 {
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return code;
        }
    };
    match dispatch(cli) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

fn load(scene: &std::path::Path, set: &[String]) -> Result<LoadedScene, InputError> {
    load_scene(scene, set)
}

fn dispatch(cli: Cli) -> Result<(), MufeError> {
    match cli.command {
        Command::Check { scene, set } => {
            let loaded = load(&scene, &set)?;
            let solver = build_solver(&loaded)?;
            let steps = (loaded.scene.simulation.duration / solver.model.dt).ceil() as u64;
            print_model_summary(&solver, &loaded, steps);
            println!("ok: {} is valid", scene.display());
            Ok(())
        }
        Command::Run { scene, out, threads, set, max_steps, quiet } => {
            if threads == Some(0) {
                return Err(InputError::new("<command line>", "--threads", "must be ≥ 1").into());
            }
            // Validate the input before MPI starts so that a bad scene fails fast on every rank.
            let loaded = load(&scene, &set)?;
            let domain = Domain::init();
            let threads = threads.unwrap_or_else(|| {
                if domain.size() == 1 {
                    std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
                } else {
                    1
                }
            });
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build_global()
                .map_err(|e| MufeError::Run(format!("cannot start {threads} threads: {e}")))?;
            run(&domain, &loaded, &RunOptions { out, threads, max_steps, quiet }).map(|_| ())
        }
    }
}
