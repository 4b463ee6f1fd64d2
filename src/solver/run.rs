//! `mufe run`: builds the model of a scene, integrates it, and writes `DIR/results.h5`.
//! Input is validated (and every mesh built) before anything is written, so a bad scene
//! never touches an existing output directory.

use super::model::build_model;
use super::parallel::{
    build_rank_solver, gather_rows, global_ledger, partition_grains, reduce_row, GlobalMesh,
    RankHooks,
};
use super::progress::Progress;
use super::step::Solver;
use super::timing::Stage;
use crate::domain::halo::Halo;
use crate::domain::Domain;
use crate::error::{MufeError, Result};
use crate::io::results::{FieldPart, HistoryColumn, MeshPart, Provenance, ResultsWriter};
use crate::material::{cauchy_from_first_piola, von_mises};
use crate::scene::LoadedScene;
use std::path::PathBuf;
use std::time::Instant;

/// Options of one run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Threads per rank (rayon pool size).
    pub threads: usize,
    /// Stop after this many steps from t = 0.
    pub max_steps: Option<u64>,
    /// No progress or summary printing.
    pub quiet: bool,
}

/// What a finished run reports.
#[derive(Debug, Clone)]
pub struct RunSummary {
    pub steps: u64,
    pub time: f64,
    pub dt: f64,
    pub wall_s: f64,
    pub elements: usize,
    pub nodes: usize,
    pub energy: crate::energy::EnergyLedger,
    pub timing_table: String,
    pub results: PathBuf,
    /// Most contact points at one step (grain–grain per pass + wall nodes).
    pub max_contacts: usize,
    /// Largest grain–grain penetration over the run (m).
    pub max_penetration: f64,
    /// Share of step time spent in the contact stage (0..1).
    pub contact_share: f64,
}

/// Initial velocity field: each grain's rigid translation + rotation about its centre.
pub fn initial_velocities(solver_model: &super::Model, loaded: &LoadedScene) -> Vec<[f64; 3]> {
    let mut v = vec![[0.0; 3]; solver_model.num_nodes()];
    for g in &solver_model.grains {
        let spec = &loaded.scene.grains[g.global_id as usize];
        let (u, w, c) = (spec.velocity, spec.angular_velocity, spec.centre);
        for n in g.nodes.clone() {
            let x = solver_model.x0[n];
            let r = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
            v[n] = [
                u[0] + w[1] * r[2] - w[2] * r[1],
                u[1] + w[2] * r[0] - w[0] * r[2],
                u[2] + w[0] * r[1] - w[1] * r[0],
            ];
        }
    }
    v
}

/// Builds the solver for a scene (all grains on this rank).
pub fn build_solver(loaded: &LoadedScene) -> Result<Solver> {
    let owned: Vec<usize> = (0..loaded.scene.grains.len()).collect();
    let (model, motions) = build_model(loaded, &owned)?;
    let v0 = initial_velocities(&model, loaded);
    Ok(Solver::new(model, motions, v0))
}

/// The `/history` columns of a solver: energies, then one group per prescribed motion.
pub fn history_columns(solver: &Solver) -> Vec<HistoryColumn> {
    let mut c = vec![
        HistoryColumn::new("time", "s", None, "simulated time t_n"),
        HistoryColumn::new("step", "", None, "step number n"),
        HistoryColumn::new(
            "kinetic_energy",
            "J",
            Some("ALLKE"),
            "½ v(n−½)·M v(n+½), consistent with central differences",
        ),
        HistoryColumn::new(
            "strain_energy",
            "J",
            Some("ALLSE"),
            "elastic strain energy Σ V0 W(F)",
        ),
        HistoryColumn::new(
            "recoverable_strain_energy",
            "J",
            None,
            "recoverable part of the strain energy",
        ),
        HistoryColumn::new(
            "internal_energy",
            "J",
            Some("ALLIE"),
            "strain + plastic dissipation + contact spring energy",
        ),
        HistoryColumn::new(
            "plastic_dissipation",
            "J",
            Some("ALLPD"),
            "energy dissipated by plastic flow",
        ),
        HistoryColumn::new(
            "friction_dissipation",
            "J",
            Some("ALLFD"),
            "energy dissipated by Coulomb friction, Σ f_t·Δslip",
        ),
        HistoryColumn::new(
            "external_work",
            "J",
            Some("ALLWK"),
            "work of prescribed motions, walls and body forces",
        ),
        HistoryColumn::new(
            "damping_dissipation",
            "J",
            Some("ALLVD"),
            "energy removed by mass-proportional damping and normal contact damping",
        ),
        HistoryColumn::new(
            "energy_balance",
            "J",
            Some("ETOTAL"),
            "ALLKE + ALLIE + ALLVD + ALLFD − ALLWK",
        ),
    ];
    for name in &solver.model.boundary_names {
        for (what, units, desc) in [
            (
                "force",
                "N",
                "reaction force the prescribed motion exerts on the grain",
            ),
            (
                "moment",
                "N*m",
                "reaction moment about the motion's current centre",
            ),
            ("displacement", "m", "displacement of the motion's centre"),
            (
                "rotation",
                "rad",
                "rotation vector of the prescribed rotation",
            ),
        ] {
            for axis in ["x", "y", "z"] {
                c.push(HistoryColumn::new(
                    &format!("{name}_{what}_{axis}"),
                    units,
                    None,
                    desc,
                ));
            }
        }
    }
    let cm = &solver.model.contact;
    if cm.active() {
        c.push(HistoryColumn::new(
            "contacts",
            "",
            None,
            "active contact points: grain–grain (per pass) plus wall nodes",
        ));
        c.push(HistoryColumn::new(
            "max_penetration",
            "m",
            None,
            "largest grain–grain penetration depth at this step",
        ));
        c.push(HistoryColumn::new(
            "contact_energy",
            "J",
            None,
            "elastic energy stored in the contact penalty springs (part of ALLIE)",
        ));
    }
    for w in &cm.walls {
        for (what, units, desc) in [
            ("force", "N", "force the wall exerts on the grains"),
            ("displacement", "m", "displacement of the wall since t = 0"),
        ] {
            for axis in ["x", "y", "z"] {
                c.push(HistoryColumn::new(
                    &format!("{}_{what}_{axis}", w.name),
                    units,
                    None,
                    desc,
                ));
            }
        }
    }
    c
}

/// How each column of [`history_columns`] combines over ranks.
pub fn history_reductions(solver: &Solver) -> Vec<super::parallel::Reduce> {
    use super::parallel::Reduce;
    let mut k = vec![Reduce::Same, Reduce::Same];
    k.extend([Reduce::Sum; 9]);
    k.extend(std::iter::repeat_n(
        Reduce::Sum,
        12 * solver.model.boundary_names.len(),
    ));
    if solver.model.contact.active() {
        k.extend([Reduce::Sum, Reduce::Max, Reduce::Sum]);
    }
    for _ in &solver.model.contact.walls {
        k.extend([Reduce::Sum; 3]);
        k.extend([Reduce::Same; 3]);
    }
    k
}

/// One history row matching [`history_columns`].
pub fn history_row(solver: &Solver, row: &mut Vec<f64>) {
    let s = &solver.state;
    let e = &s.energy;
    row.clear();
    row.extend_from_slice(&[
        // energies, reactions and wall forces of a step describe t_n, the start of the step
        // that has just been taken
        if s.step > 0 {
            s.time - solver.model.dt
        } else {
            s.time
        },
        s.step.saturating_sub(1) as f64,
        e.kinetic,
        e.strain,
        e.recoverable_strain,
        e.internal(),
        e.plastic_dissipation,
        e.friction_dissipation,
        e.external_work(),
        e.damping_dissipation(),
        e.total(),
    ]);
    // a motion lives on the rank owning its grain; other ranks report zeros (summed)
    for name in &solver.model.boundary_names {
        match solver.motions.iter().position(|m| &m.name == name) {
            Some(k) => {
                let r = &s.reactions[k];
                row.extend_from_slice(&r.force);
                row.extend_from_slice(&r.moment);
                row.extend_from_slice(&r.displacement);
                row.extend_from_slice(&r.rotation);
            }
            None => row.extend_from_slice(&[0.0; 12]),
        }
    }
    if solver.model.contact.active() {
        let c = &s.contact;
        row.extend_from_slice(&[c.contacts() as f64, c.stats.max_penetration, c.stats.energy]);
    }
    for w in &s.contact.walls {
        row.extend_from_slice(&w.force);
        row.extend_from_slice(&w.displacement);
    }
}

/// Per-element Cauchy stress (xx, yy, zz, yz, xz, xy; Pa) and von Mises stress.
pub fn element_stresses(solver: &Solver) -> (Vec<f64>, Vec<f64>) {
    let m = &solver.model;
    let mut stress = Vec::with_capacity(6 * m.num_elements());
    let mut vm = Vec::with_capacity(m.num_elements());
    for (e, t) in m.tets.iter().enumerate() {
        let xe = t.map(|n| solver.state.x[n as usize]);
        let f = crate::element::deformation_gradient(&xe, &m.tet_reference[e].dm_inv);
        let (p, _) = m.laws[m.tet_law[e] as usize].first_piola_and_energy(&f);
        let s = cauchy_from_first_piola(&p, &f);
        stress.extend_from_slice(&[s[0], s[4], s[8], s[5], s[2], s[1]]);
        vm.push(von_mises(&s));
    }
    (stress, vm)
}

/// Writes one frame: every rank contributes its owned grains' rows, rank 0 gathers them in
/// global order and writes them (all ranks must call).
fn write_frame(
    writer: &mut ResultsWriter,
    domain: &Domain,
    solver: &Solver,
    global: &GlobalMesh,
    owner: &[u32],
    index: usize,
) -> Result<()> {
    let m = &solver.model;
    let (nn, ne) = (m.owned_nodes, m.owned_elements);
    let disp: Vec<f64> = solver.state.x[..nn]
        .iter()
        .zip(&m.x0[..nn])
        .flat_map(|(x, x0)| [x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]])
        .collect();
    let vel: Vec<f64> = solver.state.v[..nn].iter().flatten().copied().collect();
    let (stress, vm) = element_stresses(solver);
    let gather = |local: &[f64], offsets: &[usize], k: usize| {
        gather_rows(domain, owner, offsets, local, k).unwrap_or_default()
    };
    let disp = gather(&disp, &global.node_offset, 3);
    let vel = gather(&vel, &global.node_offset, 3);
    let stress = gather(&stress[..6 * ne], &global.element_offset, 6);
    let vm = gather(&vm[..ne], &global.element_offset, 1);
    let (n, e) = (global.total_nodes() as u64, global.total_elements() as u64);
    let fields = [
        FieldPart {
            name: "displacement",
            units: "m",
            components: 3,
            data: &disp,
            offset: 0,
            total: n,
        },
        FieldPart {
            name: "velocity",
            units: "m/s",
            components: 3,
            data: &vel,
            offset: 0,
            total: n,
        },
        FieldPart {
            name: "stress",
            units: "Pa",
            components: 6,
            data: &stress,
            offset: 0,
            total: e,
        },
        FieldPart {
            name: "von_mises_stress",
            units: "Pa",
            components: 1,
            data: &vm,
            offset: 0,
            total: e,
        },
    ];
    writer.write_frame(index, solver.state.time, &fields)
}

/// The energy ledger over time, drawn as `DIR/energy.png` at the end of a run.
#[derive(Default)]
struct EnergyPlot {
    /// (t, ALLKE, ALLIE, ALLWK, ALLFD, ALLVD, ETOTAL) per history row.
    rows: Vec<[f64; 7]>,
}

impl EnergyPlot {
    /// Takes the columns it needs from a history row (layout of [`history_columns`]).
    fn push(&mut self, row: &[f64]) {
        self.rows
            .push([row[0], row[2], row[5], row[8], row[7], row[9], row[10]]);
    }

    fn draw(&self, path: &std::path::Path) -> Result<()> {
        use crate::io::plot::{draw, Plot, Scale, Series};
        let names = [
            "kinetic ALLKE",
            "internal ALLIE",
            "external work ALLWK",
            "friction ALLFD",
            "damping ALLVD",
            "balance ETOTAL",
        ];
        let series = names
            .iter()
            .enumerate()
            .map(|(k, name)| Series {
                label: (*name).into(),
                points: self.rows.iter().map(|r| (r[0] * 1e6, r[k + 1])).collect(),
                theory: k == 5,
            })
            .collect();
        draw(
            path,
            &Plot {
                title: "energy ledger",
                x_label: "time (µs)",
                y_label: "energy (J)",
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series,
            },
        )
        .map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))
    }
}

/// Measured load balance and ghost re-planning between steps (MPI runs only).
struct LoadBalance {
    /// Compute time (s) of this rank at the last check.
    last_compute: f64,
    /// Owned node positions at the last (re)plan, for the ghost-margin check.
    x_at_plan: Vec<[f64; 3]>,
    /// Halo plan of a new decomposition, handed to the caller.
    halo: Option<crate::domain::halo::HaloPlan>,
    /// The solver when nothing changed.
    kept: Option<Solver>,
}

impl LoadBalance {
    fn new(solver: &Solver) -> Self {
        Self {
            last_compute: 0.0,
            x_at_plan: solver.state.x[..solver.model.owned_nodes].to_vec(),
            halo: None,
            kept: None,
        }
    }

    fn compute_seconds(solver: &Solver) -> f64 {
        let t = &solver.timers;
        t.seconds(Stage::InternalForces)
            + t.seconds(Stage::Contact)
            + t.seconds(Stage::Boundary)
            + t.seconds(Stage::Integrate)
    }

    fn take_back(&mut self) -> Solver {
        self.kept.take().expect("solver kept by the last check")
    }

    /// Re-partitions when the measured imbalance exceeds the threshold (vertex weights: each
    /// rank's measured compute time spread over its grains by the static cost model), or
    /// re-plans the ghosts when some grain moved by more than a quarter of the ghost margin.
    /// Returns the new solver and owner table when grains or ghosts changed. All ranks
    /// must call.
    fn check(
        &mut self,
        domain: &Domain,
        loaded: &LoadedScene,
        global: &GlobalMesh,
        solver: Solver,
        owner: &[u32],
    ) -> Result<Option<(Solver, Vec<u32>, usize)>> {
        let spec = &loaded.scene.parallel;
        let now = Self::compute_seconds(&solver);
        let mine = now - self.last_compute;
        self.last_compute = now;
        let times: Vec<f64> = domain
            .all_gather_u64(mine.to_bits())
            .into_iter()
            .map(f64::from_bits)
            .collect();
        let imbalance = crate::domain::decomposition::imbalance(&times);
        let moved = solver.state.x[..solver.model.owned_nodes]
            .iter()
            .zip(&self.x_at_plan)
            .map(|(a, b)| {
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        let mut flags = [
            if imbalance > spec.imbalance_threshold {
                1.0
            } else {
                0.0
            },
            moved,
        ];
        domain.max_in_place(&mut flags);
        let replan_ghosts = flags[1] > 0.25 * super::parallel::ghost_margin(global);
        if flags[0] == 0.0 && !replan_ghosts {
            self.kept = Some(solver);
            return Ok(None);
        }
        let n = loaded.scene.grains.len();
        let bounds = super::parallel::current_bounds(domain, &solver, owner, n);
        let new_owner = if flags[0] > 0.0 {
            super::parallel::repartition_measured(domain, global, &bounds, owner, &times)?
        } else {
            owner.to_vec()
        };
        let migrated = owner.iter().zip(&new_owner).filter(|(a, b)| a != b).count();
        let (s, _plan, halo) = super::parallel::redistribute(
            domain, loaded, global, solver, owner, &new_owner, &bounds,
        )?;
        self.x_at_plan = s.state.x[..s.model.owned_nodes].to_vec();
        self.last_compute = Self::compute_seconds(&s);
        self.halo = Some(halo);
        Ok(Some((s, new_owner, migrated)))
    }
}

/// Runs a scene to its duration (or `max_steps`) and writes the results: serially, or
/// under `mpirun` with the grains partitioned over the ranks (all ranks must call).
pub fn run(domain: &Domain, loaded: &LoadedScene, opts: &RunOptions) -> Result<RunSummary> {
    let wall0 = Instant::now();
    let global = GlobalMesh::build(loaded)?;
    let owner = partition_grains(domain, loaded, &global)?;
    let (mut solver, plan, halo_plan) = build_rank_solver(domain, loaded, &global, &owner)?;
    let mut hooks = RankHooks {
        domain,
        halo: Halo::new(domain, halo_plan),
    };
    let root = domain.is_root();
    let talk = root && !opts.quiet;
    let scene = &loaded.scene;
    let dt = solver.model.dt;
    let total_steps = (scene.simulation.duration / dt).ceil() as u64;
    let last_step = opts.max_steps.map_or(total_steps, |m| m.min(total_steps));
    if talk {
        print_model_summary(&solver, loaded, total_steps);
        if domain.size() > 1 {
            println!(
                "ranks: {} (METIS), rank 0 owns {} grains and mirrors {} ghosts; halo {} bytes/step from rank 0",
                domain.size(),
                plan.owned.len(),
                plan.ghosts.len(),
                hooks.halo.plan.bytes_per_step()
            );
        }
    }

    std::fs::create_dir_all(&opts.out).map_err(|e| {
        MufeError::Io(format!(
            "{}: cannot create output directory: {e}",
            opts.out.display()
        ))
    })?;
    let results = opts.out.join(crate::io::results::RESULTS_FILE_NAME);
    let provenance = Provenance::collect(domain, opts.threads);
    let mut writer = ResultsWriter::create(domain, &results, &loaded.text, &provenance)?;
    // /mesh from the global layout (identical on all ranks); rank 0 writes it.
    let (mut nodes, mut tets64, mut grain_of_tet) = (Vec::new(), Vec::new(), Vec::new());
    if root {
        for (g, spec) in scene.grains.iter().enumerate() {
            let mesh = &global.meshes[g];
            let base = global.node_offset[g] as u64;
            nodes.extend(mesh.nodes.iter().map(|p| {
                [
                    p[0] + spec.centre[0],
                    p[1] + spec.centre[1],
                    p[2] + spec.centre[2],
                ]
            }));
            tets64.extend(mesh.tets.iter().map(|t| t.map(|n| n as u64 + base)));
            grain_of_tet.extend(std::iter::repeat_n(g as u32, mesh.tets.len()));
        }
    }
    writer.write_mesh(&MeshPart {
        nodes: &nodes,
        node_offset: 0,
        total_nodes: global.total_nodes() as u64,
        tets: &tets64,
        tet_offset: 0,
        total_tets: global.total_elements() as u64,
        grain_of_tet: &grain_of_tet,
        grain_owner_rank: &owner,
    })?;
    drop((nodes, tets64, grain_of_tet));
    writer.define_history(&history_columns(&solver))?;

    let history_interval = scene
        .output
        .history_interval
        .unwrap_or(scene.simulation.duration / 1000.0);
    let history_every = ((history_interval / dt).round() as u64).max(1);
    let frame_every = scene
        .output
        .frame_interval
        .map(|f| ((f / dt).round() as u64).max(1));
    let mut frame_index = 0;
    if scene.output.frames {
        write_frame(&mut writer, domain, &solver, &global, &owner, frame_index)?;
        frame_index += 1;
    }
    let reductions = history_reductions(&solver);
    let mut energy_plot = EnergyPlot::default();
    let mut progress = Progress::new(talk, "run");
    let mut row = Vec::new();
    let mut failure = None;
    let mut owner = owner;
    let mut balance = LoadBalance::new(&solver);
    while solver.state.step < last_step {
        if let Err(e) = solver.step_with(&mut hooks) {
            if domain.size() > 1 {
                // the other ranks cannot know: stop the whole job rather than hang
                eprintln!("rank {}: error: {e}", domain.rank());
                domain.abort(e.exit_code().max(1));
            }
            failure = Some(e);
            break;
        }
        let n = solver.state.step;
        let t_out = Instant::now();
        if n % history_every == 0 || n == last_step {
            history_row(&solver, &mut row);
            reduce_row(domain, &reductions, &mut row);
            writer.push_history(&row)?;
            energy_plot.push(&row);
        }
        if let Some(fe) = frame_every {
            if n % fe == 0 && n != last_step && scene.output.frames {
                write_frame(&mut writer, domain, &solver, &global, &owner, frame_index)?;
                frame_index += 1;
                writer.flush_history()?;
            }
        }
        solver.timers.add(Stage::Output, t_out.elapsed());
        progress.update(n as f64 / last_step as f64, n, solver.state.time);
        if domain.size() > 1 && n % scene.parallel.check_interval == 0 && n != last_step {
            // complete the halo in flight before grains may change hands
            hooks.halo.end(&mut solver.state.x, &mut solver.state.v)?;
            if let Some((s, new_owner, moved)) =
                balance.check(domain, loaded, &global, solver, &owner)?
            {
                solver = s;
                if talk {
                    println!(
                        "re-partitioned at step {n}: {moved} grains migrated (imbalance above {})",
                        scene.parallel.imbalance_threshold
                    );
                }
                owner = new_owner;
                hooks = RankHooks {
                    domain,
                    halo: Halo::new(domain, balance.halo.take().unwrap_or_default()),
                };
            } else {
                solver = balance.take_back();
                hooks.halo.begin(&solver.state.x, &solver.state.v)?;
            }
        }
    }
    progress.finish();
    // Keep what was computed up to a failure: history and a last frame help diagnose it.
    if failure.is_some() || solver.state.step == 0 {
        history_row(&solver, &mut row);
        reduce_row(domain, &reductions, &mut row);
        writer.push_history(&row)?;
        energy_plot.push(&row);
    }
    if scene.output.frames {
        write_frame(&mut writer, domain, &solver, &global, &owner, frame_index)?;
    }
    writer.close()?;
    if root {
        energy_plot.draw(&opts.out.join("energy.png"))?;
    }
    // the summary reports global quantities
    let energy = global_ledger(domain, &solver.state.energy);
    let mut maxima = [
        solver.state.contact.stats.max_penetration_run,
        solver.state.contact.stats.max_contacts_run as f64,
    ];
    domain.max_in_place(&mut maxima);
    let mut contacts_now = [
        solver.state.contact.contacts() as f64,
        solver.state.contact.stats.rebuilds as f64,
    ];
    domain.sum_in_place(&mut contacts_now[..1]);
    if let Some(e) = failure {
        return Err(e);
    }
    let summary = RunSummary {
        steps: solver.state.step,
        time: solver.state.time,
        dt,
        wall_s: wall0.elapsed().as_secs_f64(),
        elements: solver.model.num_elements(),
        nodes: solver.model.num_nodes(),
        energy,
        timing_table: solver.timers.table(solver.state.step),
        results: results.clone(),
        max_contacts: maxima[1] as usize,
        max_penetration: maxima[0],
        contact_share: solver.timers.share(Stage::Contact),
    };
    if talk {
        let e = &summary.energy;
        println!("{}", summary.timing_table);
        println!(
            "done: {} steps to t = {:.6e} s in {:.2} s wall ({:.3e} element updates/s)",
            summary.steps,
            summary.time,
            summary.wall_s,
            summary.elements as f64 * summary.steps as f64
                / solver.timers.total_seconds().max(1e-9)
        );
        println!(
            "energy: kinetic {:.4e} J, strain {:.4e} J, external work {:.4e} J, damping {:.4e} J, balance error {:.2e} (relative)",
            e.kinetic,
            e.strain,
            e.external_work(),
            e.damping_dissipation(),
            e.relative_balance_error()
        );
        if solver.model.contact.active() {
            println!(
                "contact: {} points now, at most {}; max penetration {:.3e} m ({:.2e} × smallest surface edge); {} broad-phase rebuilds; {:.1}% of step time in contact",
                contacts_now[0],
                summary.max_contacts,
                summary.max_penetration,
                summary.max_penetration / solver.model.contact.min_edge.max(f64::MIN_POSITIVE),
                contacts_now[1],
                100.0 * summary.contact_share
            );
        }
        println!("results: {}", results.display());
    }
    Ok(summary)
}

/// The `mufe check`/`run` header: grains, elements, nodes, Δt, mass scaling, memory.
pub fn print_model_summary(solver: &Solver, loaded: &LoadedScene, total_steps: u64) {
    let m = &solver.model;
    println!("scene: {}", loaded.path);
    println!(
        "{:<12} {:>10} {:>10} {:>9} {:>9} {:>10} {:>10}",
        "grain", "elements", "nodes", "facets", "min dih°", "max aspect", "min edge m"
    );
    for g in m.grains.iter().take(20) {
        let q = &g.quality;
        println!(
            "{:<12} {:>10} {:>10} {:>9} {:>9.2} {:>10.2} {:>10.3e}",
            g.name,
            q.elements,
            q.nodes,
            q.surface_facets,
            q.min_dihedral_deg,
            q.max_aspect_ratio,
            q.min_edge
        );
    }
    if m.grains.len() > 20 {
        println!("... {} more grains", m.grains.len() - 20);
    }
    let phys = m.total_physical_mass();
    println!(
        "totals: {} grains, {} elements, {} nodes; mass {:.4e} kg",
        m.grains.len(),
        m.num_elements(),
        m.num_nodes(),
        phys
    );
    println!(
        "time step: stable {:.4e} s (element {}, safety {}), used {:.4e} s; {} steps for {:.4e} s",
        m.dt_stable,
        m.dt_critical_element,
        loaded.scene.simulation.dt_safety,
        m.dt,
        total_steps,
        loaded.scene.simulation.duration
    );
    if m.scaled_elements > 0 {
        println!(
            "mass scaling: {} elements scaled, added mass {:.4e} kg ({:.3}% of {:.4e} kg)",
            m.scaled_elements,
            m.added_mass,
            100.0 * m.added_mass / phys,
            phys
        );
    }
    let cm = &m.contact;
    if cm.active() {
        let st = &cm.stable_step;
        if cm.grain_contact {
            println!(
                "contact: friction {}, penalty factor {} (max ε_n {:.3e} Pa/m), damping {} of critical, margin {:.3e} m, {} surface nodes, {} facets, {} walls",
                cm.friction,
                cm.penalty_factor,
                st.max_penalty,
                cm.damping,
                cm.margin,
                cm.node.len(),
                cm.facet.len(),
                cm.walls.len()
            );
        } else {
            println!(
                "contact: {} walls (kinematic), margin {:.3e} m",
                cm.walls.len(),
                cm.margin
            );
        }
        if st.contact_dt.is_finite() {
            println!(
                "contact stable step: {:.4e} s (node {}) vs {:.4e} s from elements alone (×{:.3}){}",
                st.contact_dt,
                st.critical_node.unwrap_or(0),
                st.element_dt,
                (st.contact_dt / st.element_dt).min(1.0),
                if st.scaled_nodes > 0 {
                    format!("; {} contact nodes mass-scaled, added {:.4e} kg", st.scaled_nodes, st.added_mass)
                } else {
                    String::new()
                }
            );
        }
    }
    let bytes = estimate_memory_bytes(m);
    println!(
        "memory estimate: {:.1} MiB ({:.0} bytes/element)",
        bytes as f64 / 1048576.0,
        bytes as f64 / m.num_elements().max(1) as f64
    );
}

/// Bytes held by the model, state and scratch arrays.
pub fn estimate_memory_bytes(m: &super::Model) -> usize {
    let ne = m.num_elements();
    let nn = m.num_nodes();
    let per_element = 16 /* tets */ + 80 /* reference */ + 2 /* law */ + 96 /* corner forces */ + 16 /* incidence */;
    let per_node = 24 * 5 /* x0, x, v, v_next, force */ + 16 /* masses */ + 1 + 4;
    ne * per_element + nn * per_node
}
