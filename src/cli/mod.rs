//! Command-line interface (README, docs/INPUT.md). `main` only parses and dispatches here; every
//! error becomes one line on stderr and an exit code (2 for bad input).

use crate::domain::Domain;
use crate::driver::{print_model_summary, run, RunOptions};
use crate::error::{InputError, MufeError};
use crate::scene::LoadedScene;
use crate::solver::build_solver;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

mod guards;
mod parse_errors;
mod scene_partition;

use guards::{
    blame_packing, check_estimate, check_out_dir, estimate_and_guard, load, thread_binding_warning,
};
pub use parse_errors::clap_error;
use scene_partition::partition_command;
pub use scene_partition::{scene_partition_grains, ScenePartitionGrain};

#[derive(Debug, Parser)]
#[command(
    name = "mufe",
    version,
    about = "Micro finite-element (μFE) simulator for granular soil"
)]
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
        /// Run even if the estimate before meshing says the scene will not fit in memory
        /// or needs more than a billion steps.
        #[arg(long)]
        force: bool,
        /// Write a checkpoint into OUT/checkpoints/ every N steps (replaces the scene's
        /// output.checkpoint_every).
        #[arg(long, value_name = "N")]
        checkpoint_every: Option<u64>,
        /// Continue from a checkpoint (OUT/checkpoints/step_N.h5, or `latest`: the newest
        /// valid one of OUT/checkpoints/) written for this scene and --set values (output
        /// settings and simulation.duration may differ); any rank count, re-partitioning
        /// when it differs. OUT/results.h5 is continued.
        #[arg(long, value_name = "CHECKPOINT|latest")]
        restart: Option<PathBuf>,
        /// With --restart: start a new run in a new --out from the checkpoint although the
        /// scene differs (friction, stages, rates); recorded in /provenance.
        #[arg(long, requires = "restart")]
        branch: bool,
    },
    /// Validate a scene without running: grains, elements, nodes, stable Δt, mass scaling, memory.
    Check {
        scene: PathBuf,
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Mesh and report even if the estimate says the scene will not fit in memory or
        /// needs more than a billion steps.
        #[arg(long)]
        force: bool,
    },
    /// Partition the scene's grains with METIS; report balance, edge cut and halo size.
    Partition {
        scene: PathBuf,
        /// Number of parts (MPI ranks), 1 ≤ N ≤ number of grains.
        #[arg(long, value_name = "N")]
        parts: usize,
        /// Write the partition (`grain_id part` per line) to this file.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
        /// Contact margin (m): grains whose bounding spheres come closer than this are
        /// neighbours. Default: 0.1 × the median bounding radius.
        #[arg(long, value_name = "M", allow_hyphen_values = true)]
        margin: Option<f64>,
        /// Mesh every distinct grain shape (once) to count elements and surface nodes
        /// exactly, instead of estimating them from the shape.
        #[arg(long)]
        exact: bool,
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Mesh even if the estimate says the scene will not fit in memory.
        #[arg(long)]
        force: bool,
    },
    /// Write a virtual sand: N irregular grains as binary STL files (mm) and DIR/scene.toml
    /// placing them on a loose grid between two walls (docs/SHAPES.md).
    Sand {
        /// Output directory (created if needed).
        #[arg(long)]
        out: PathBuf,
        /// Number of grains.
        #[arg(long, default_value_t = 8)]
        grains: usize,
        /// Random seed: the same seed and parameters give the same files.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Longest over middle semi-axis a/b (≥ 1).
        #[arg(long, default_value_t = 1.4)]
        elongation: f64,
        /// Middle over shortest semi-axis b/c (≥ 1).
        #[arg(long, default_value_t = 1.25)]
        flatness: f64,
        /// Relative amplitude of the surface waves (0 … 0.3).
        #[arg(long, default_value_t = 0.08)]
        roughness: f64,
        /// Equivalent diameter (m).
        #[arg(long, default_value_t = 1e-3)]
        size: f64,
        /// Mesh seeding written into the scene (m); default size/5.
        #[arg(long)]
        seeding: Option<f64>,
        /// Icosphere level of the surfaces: 20·4^level facets (1 … 6).
        #[arg(long, default_value_t = 3)]
        level: u32,
        /// Also write DIR/labels.nrrd and DIR/labels.tif: the grains packed 0.9 equivalent diameters apart
        /// (neighbours meet over faces) and voxelised with this voxel edge (m), an input
        /// for `mufe import`.
        #[arg(long)]
        image_voxel: Option<f64>,
        /// Write a box of six walls and five stages instead (deposit from a checkerboard
        /// start under 200 g, damped; lower the top wall until it touches; approach until it
        /// carries 10 kPa; consolidate: servo-held at 100 kPa; compress: a constant strain
        /// rate), with frames: the shape demo of jobs/shapes/ (docs/SHAPES.md, "Demo").
        #[arg(long = "box")]
        in_box: bool,
    },
    /// Internal: mesh the JSON surface spec on stdin into the disk cache (started by mufe
    /// itself to mesh distinct shapes in parallel).
    #[command(hide = true)]
    MeshWorker,
    /// Import a labelled μCT image (NRRD or 3-D TIFF; 0 = void, one integer label per grain) as a
    /// scene of grains: one volume mesh per label beside SCENE and SCENE itself, which
    /// `mufe check` accepts (docs/SHAPES.md, "Label images").
    Import {
        /// The label image: .nrrd/.nhdr (raw or ascii encoding) or a .tif/.tiff stack (one
        /// grayscale page per slice; ImageJ spacing).
        labels: PathBuf,
        /// Scene file to write; the grains go to <stem>_grains/ beside it.
        #[arg(long)]
        out: PathBuf,
        /// Voxel edge (m); default: the header's spacing with its `space units`.
        #[arg(long)]
        voxel_size: Option<f64>,
        /// Surface edge to coarsen to, also the grains' mesh seeding (m); default 2 voxels.
        #[arg(long)]
        seeding: Option<f64>,
        /// Taubin smoothing passes of the voxel surfaces.
        #[arg(long, default_value_t = 10)]
        smoothing: usize,
        /// Gap to leave between grains that touch in the image (m, below half a voxel);
        /// default 0: their contact faces coincide.
        #[arg(long, default_value_t = 0.0)]
        gap: f64,
        /// Labels with fewer voxels are left out (and listed).
        #[arg(long, default_value_t = 27)]
        min_voxels: usize,
    },
    /// Draw the energy study figures of one or more runs (external work, strain energy,
    /// plastic and frictional dissipation, dissipation indices; docs/RESULTS.md) and print
    /// the energy ledger at the peak stress ratio and at the end of each run.
    Plot {
        /// results.h5 files, drawn side by side.
        #[arg(required = true, value_name = "RESULTS.h5")]
        results: Vec<PathBuf>,
        /// Directory for the PNGs (default: the first file's directory).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Legend label of each file, in order (default: the file's directory name).
        #[arg(long = "label", value_name = "NAME")]
        labels: Vec<String>,
    },
    /// Run analytic validation cases (hertz, mindlin, mindlin_cyclic, torsion, rolling,
    /// plastic_cube, plastic_spheres) over meshing ratios; print a table, write
    /// DIR/validation.json, one PNG per case and each run's results.h5 + energy.png.
    Validate {
        /// Cases to run (default: all).
        cases: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "out/validation")]
        out: PathBuf,
        /// Meshing ratios at the contact, comma separated (default: per case).
        #[arg(long, value_name = "LIST")]
        mr: Option<String>,
        /// Coarse meshes and looser documented tolerances (what `cargo test` runs).
        #[arg(long)]
        quick: bool,
        /// Threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Override a field of every case scene (material, radius and friction also set
        /// the generated drive, loads and meshes).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Set a dimensionless scene-generator parameter, e.g. `hertz.v_plate=1e-4`
        /// (units and defaults: src/validate/scenes/).
        #[arg(long = "param", value_name = "CASE.KEY=VALUE")]
        param: Vec<String>,
        /// Write the generated scenes of the cases to DIR (for the material, radius and
        /// friction after --set) and exit without running them.
        #[arg(long, value_name = "DIR")]
        write_scenes: Option<PathBuf>,
    },
}

/// Runs the CLI and returns the process exit code.
pub fn main_with_args(args: impl IntoIterator<Item = std::ffi::OsString>) -> i32 {
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            if !e.use_stderr() {
                // --help, --version
                let _ = e.print();
                return 0;
            }
            crate::error::report_line(format_args!("error: {}", clap_error(&e)));
            return 2;
        }
    };
    match dispatch(cli) {
        Ok(()) => 0,
        Err(e @ MufeError::Stopped { .. }) => {
            crate::error::report_line(format_args!("stopped: {e}"));
            e.exit_code()
        }
        Err(e) => {
            crate::error::report_line(format_args!("error: {e}"));
            e.exit_code()
        }
    }
}

const GIB: f64 = (1u64 << 30) as f64;

fn dispatch(cli: Cli) -> Result<(), MufeError> {
    match cli.command {
        Command::Check { scene, set, force } => {
            let loaded = load(&scene, &set)?;
            let (est, copies) = check_estimate(&loaded, force)?;
            let solver = match &copies {
                Some((reps, _)) => crate::solver::build_solver_for(&loaded, reps, &[]),
                None => build_solver(&loaded),
            }
            .map_err(|e| blame_packing(&loaded, e))?;
            let steps = (loaded.scene.simulation.duration / solver.model.dt).ceil();
            if !force && (steps.is_nan() || steps > crate::scene::estimate::MAX_STEPS as f64) {
                return Err(InputError::new(
                    &loaded.path,
                    est.dt_field,
                    format!(
                        "duration / Δt {:.3e} s = {steps:.3e} steps, more than the limit of {:.0e}; use a shorter duration or a larger step, or --force",
                        solver.model.dt,
                        crate::scene::estimate::MAX_STEPS as f64
                    ),
                )
                .into());
            }
            let steps = if steps.is_finite() && steps < 1.8e19 {
                steps as u64
            } else {
                u64::MAX
            };
            match &copies {
                Some((_, n)) => {
                    crate::driver::print_representative_summary(&solver, &loaded, steps, n)
                }
                None => print_model_summary(&solver, &loaded, steps),
            }
            println!("{}", est.summary());
            if copies.is_some() {
                println!("note: initial overlaps were checked on the grains' spheres and boxes; the mesh-level check runs with `mufe run`");
                if let Some((available, source)) = crate::scene::estimate::memory_limit()? {
                    if est.memory_bytes > available {
                        println!(
                            "note: `mufe run` needs about {:.1} GiB (estimate before meshing), more than the {:.1} GiB available here ({source}); run it on a larger machine or across more MPI ranks",
                            est.memory_bytes as f64 / GIB,
                            available as f64 / GIB
                        );
                    }
                }
            }
            print_shape_descriptors(&loaded);
            println!("ok: {} is valid", scene.display());
            Ok(())
        }
        Command::Run {
            scene,
            out,
            threads,
            set,
            max_steps,
            quiet,
            force,
            checkpoint_every,
            restart,
            branch,
        } => {
            if checkpoint_every == Some(0) {
                return Err(InputError::new(
                    "<command line>",
                    "--checkpoint-every",
                    "must be ≥ 1 step",
                )
                .into());
            }
            if threads == Some(0) {
                return Err(InputError::new("<command line>", "--threads", "must be ≥ 1").into());
            }
            check_out_dir(&out)?;
            // Validate the input before MPI starts so that a bad scene fails fast on every rank.
            let loaded = load(&scene, &set)?;
            // With --max-steps the run stops early: the step limit applies to what is run.
            let step_limit = crate::scene::estimate::MAX_STEPS;
            let est = estimate_and_guard(&loaded, force, None)?;
            if !force && max_steps.is_none_or(|m| m > step_limit) {
                crate::scene::estimate::guard(&loaded.path, &est, None, Some(step_limit))?;
            }
            let domain = Domain::init();
            let available = std::thread::available_parallelism().map_or(1, |n| n.get());
            let warning = threads.and_then(|t| thread_binding_warning(t, available));
            if let Some(w) = warning.filter(|_| domain.rank() == 0) {
                crate::error::report_line(w);
            }
            let threads = threads.unwrap_or(if domain.size() == 1 { available } else { 1 });
            start_threads(threads)?;
            run(
                &domain,
                &loaded,
                &RunOptions {
                    out,
                    threads,
                    max_steps,
                    quiet,
                    force,
                    checkpoint_every,
                    restart,
                    branch,
                },
            )
            .map(|_| ())
            .map_err(|e| blame_packing(&loaded, e))
        }
        Command::Validate {
            cases,
            out,
            mr,
            quick,
            threads,
            set,
            param,
            write_scenes,
        } => {
            if let Some(dir) = std::env::var_os("MUFE_VALIDATION_SCENES") {
                if !std::path::Path::new(&dir).is_dir() {
                    return Err(InputError::new(
                        "<environment>",
                        "MUFE_VALIDATION_SCENES",
                        format!(
                            "'{}' is not a directory",
                            crate::error::echo(&dir.to_string_lossy())
                        ),
                    )
                    .into());
                }
            }
            let selected = crate::validate::select_cases(&cases)?;
            let mrs = mr
                .as_deref()
                .map(|m| crate::validate::runner::parse_mr_list(m, &selected))
                .transpose()?;
            let mut params = crate::validate::scenes::Params::default();
            for p in &param {
                params.set(p)?;
            }
            if let Some(dir) = write_scenes {
                let written =
                    crate::validate::runner::write_scenes(&selected, &dir, &set, &params)?;
                for p in written {
                    println!("wrote {}", p.display());
                }
                return Ok(());
            }
            if let Some(t) = threads {
                if t == 0 {
                    return Err(
                        InputError::new("<command line>", "--threads", "must be ≥ 1").into(),
                    );
                }
                start_threads(t)?;
            }
            // the runs write their results.h5 through the same (MPI-IO) output as `mufe run`
            let domain = Domain::init();
            let outcomes = crate::validate::runner::run_cases(
                &selected,
                mrs.as_deref(),
                quick,
                &out,
                &set,
                &params,
                &domain,
            )?;
            let failed: Vec<String> = outcomes
                .iter()
                .filter(|o| !o.pass)
                .map(|o| format!("{} at MR {}", o.case, o.mr))
                .collect();
            // The finest MR of each case must meet its target; coarser ones document convergence.
            let finest_failed = crate::validate::finest_failures(&outcomes);
            if !finest_failed.is_empty() {
                return Err(MufeError::Run(format!(
                    "validation target missed at the finest MR: {}",
                    finest_failed.join(", ")
                )));
            }
            if !failed.is_empty() {
                println!("note: coarser meshes above target: {}", failed.join(", "));
            }
            Ok(())
        }
        Command::Partition {
            scene,
            parts,
            out,
            margin,
            exact,
            set,
            force,
        } => partition_command(&scene, &set, parts, out.as_deref(), margin, exact, force),
        Command::Plot {
            results,
            out,
            labels,
        } => plot_command(&results, out, &labels),
        Command::MeshWorker => crate::mesh::import::run_mesh_worker()
            .map_err(|e| InputError::new("<stdin>", "mesh-worker", e).into()),
        Command::Import {
            labels,
            out,
            voxel_size,
            seeding,
            smoothing,
            gap,
            min_voxels,
        } => {
            let opts = crate::image::scene::ImportOptions {
                voxel_size,
                seeding,
                smoothing,
                gap,
                min_voxels,
            };
            crate::image::scene::import_command(&labels, &out, &opts)
        }
        Command::Sand {
            out,
            grains,
            seed,
            elongation,
            flatness,
            roughness,
            size,
            seeding,
            level,
            image_voxel,
            in_box,
        } => {
            let p = crate::sand::SandParams {
                grains,
                seed,
                elongation,
                flatness,
                roughness,
                size,
                seeding: seeding.unwrap_or(size / 5.0),
                level,
            };
            check_sand_params(&p)?;
            if let Some(voxel) = image_voxel {
                if !(voxel.is_finite() && voxel > 0.0 && voxel <= p.size / 4.0) {
                    return Err(InputError::new(
                        "<command line>",
                        "--image-voxel",
                        format!(
                            "must be > 0 and at most a quarter of --size ({} m), got {voxel}",
                            crate::error::num(p.size / 4.0)
                        ),
                    )
                    .into());
                }
            }
            check_out_dir(&out)?;
            let write = if in_box {
                crate::sand::write_sand_box
            } else {
                crate::sand::write_sand
            };
            let path = write(&out, &p).map_err(|e| {
                MufeError::Io(format!("{}: cannot write the sand: {e}", out.display()))
            })?;
            println!("wrote {grains} grains and {}", path.display());
            if let Some(voxel) = image_voxel {
                let (path, image) =
                    crate::sand::write_sand_image(&out, &p, voxel).map_err(|e| {
                        MufeError::Io(format!("{}: cannot write the image: {e}", out.display()))
                    })?;
                println!(
                    "wrote {} ({} × {} × {} voxels of {voxel:e} m)",
                    path.display(),
                    image.size[0],
                    image.size[1],
                    image.size[2]
                );
            }
            Ok(())
        }
    }
}

/// `mufe plot`: reads every file before drawing anything, so a bad file leaves no partial
/// figures.
fn plot_command(
    results: &[PathBuf],
    out: Option<PathBuf>,
    labels: &[String],
) -> Result<(), MufeError> {
    use crate::io::energy_figures::{default_label, draw_energy_figures, ledger_table, RunHistory};
    if labels.len() > results.len() {
        return Err(InputError::new(
            "<command line>",
            "--label",
            format!("{} labels for {} files", labels.len(), results.len()),
        )
        .into());
    }
    let runs = results
        .iter()
        .enumerate()
        .map(|(i, path)| {
            let label = labels
                .get(i)
                .cloned()
                .unwrap_or_else(|| default_label(path));
            RunHistory::read(path, &label)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let out = out.unwrap_or_else(|| {
        results[0]
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map_or_else(|| PathBuf::from("."), std::path::Path::to_path_buf)
    });
    check_out_dir(&out)?;
    for path in draw_energy_figures(&runs, &out)? {
        println!("wrote {}", path.display());
    }
    print!("{}", ledger_table(&runs));
    Ok(())
}

/// One line per grain of a surface shape: its descriptors (docs/SHAPES.md).
fn print_shape_descriptors(loaded: &LoadedScene) {
    for (i, g) in loaded.scene.grains.iter().enumerate() {
        if let crate::scene::ShapeSpec::Surface(s) = &g.shape {
            if let Some(geometry) = &s.geometry {
                println!(
                    "shape of grain '{}' ({}): {}",
                    g.display_name(i),
                    s.file,
                    geometry.descriptors
                );
            }
        }
    }
}

/// The bounds of `mufe sand`'s arguments.
fn check_sand_params(p: &crate::sand::SandParams) -> Result<(), InputError> {
    let bad = |arg: &str, why: String| Err(InputError::new("<command line>", arg, why));
    if !(1..=100_000).contains(&p.grains) {
        return bad("--grains", format!("must be 1 … 100000, got {}", p.grains));
    }
    for (arg, v) in [("--elongation", p.elongation), ("--flatness", p.flatness)] {
        if !(v.is_finite() && (1.0..=10.0).contains(&v)) {
            return bad(arg, format!("must be 1 … 10, got {v}"));
        }
    }
    if !(p.roughness.is_finite() && (0.0..=0.3).contains(&p.roughness)) {
        return bad(
            "--roughness",
            format!("must be 0 … 0.3, got {}", p.roughness),
        );
    }
    for (arg, v) in [("--size", p.size), ("--seeding", p.seeding)] {
        if !(v.is_finite() && v > 0.0 && v <= 1.0) {
            return bad(arg, format!("must be a length in (0, 1] m, got {v}"));
        }
    }
    if !(1..=6).contains(&p.level) {
        return bad("--level", format!("must be 1 … 6, got {}", p.level));
    }
    Ok(())
}

/// The global thread pool of `threads` threads, the main thread one of them: a parallel
/// loop started there runs on it rather than being handed to a worker and waited for, so
/// a rank on one thread (the default under `mpirun`) has no second thread at all — no
/// wake-up per loop, and no idle worker spinning on the core the rank computes on.
fn start_threads(threads: usize) -> Result<(), MufeError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .use_current_thread()
        .build_global()
        .map_err(|e| MufeError::Run(format!("cannot start {threads} threads: {e}")))
}
