//! What a run prints: the model summary (`mufe check` and the head of `mufe run`), the
//! memory estimate, and the closing summary of `mufe run`.

pub use super::scene_counts::{estimate_memory_bytes, SceneCounts};
use super::RunSummary;
use crate::boundary::stages::{StagePlan, StageRecord, WallMode};
use crate::io::results::StageAttributes;
use crate::scene::LoadedScene;
use crate::solver::{Solver, Stage};

/// The `mufe check`/`run` header: grains, elements, nodes, Δt, mass scaling, memory.
pub fn print_model_summary(solver: &Solver, loaded: &LoadedScene, total_steps: u64) {
    print_summary(solver, loaded, total_steps, Scope::Model);
}

/// The `mufe run` header on rank 0 of several: the table lists rank 0's grains, the
/// counts, mass, mass scaling, surfaces and memory are the whole scene's (`scene`).
pub fn print_rank_summary(
    solver: &Solver,
    loaded: &LoadedScene,
    total_steps: u64,
    scene: &SceneCounts,
) {
    print_summary(solver, loaded, total_steps, Scope::Ranks(scene));
}

/// The header when the model holds one representative of each distinct grain (shape and
/// material) and `copies[g]` scene grains are like model grain `g`: totals, mass and
/// memory are those of the whole scene.
pub fn print_representative_summary(
    solver: &Solver,
    loaded: &LoadedScene,
    total_steps: u64,
    copies: &[usize],
) {
    print_summary(solver, loaded, total_steps, Scope::Representatives(copies));
}

/// What the model of a header holds.
#[derive(Clone, Copy)]
enum Scope<'a> {
    /// The whole scene.
    Model,
    /// One rank's share of a scene run on several, whose totals are given.
    Ranks(&'a SceneCounts),
    /// One grain per distinct kind, `copies[g]` scene grains each.
    Representatives(&'a [usize]),
}

fn print_summary(solver: &Solver, loaded: &LoadedScene, total_steps: u64, scope: Scope) {
    let m = &solver.model;
    let copies = match scope {
        Scope::Representatives(c) => Some(c),
        _ => None,
    };
    let copy = |g: usize| copies.map_or(1, |c| c[g]);
    println!("scene: {}", loaded.path);
    if copies.is_some() {
        println!(
            "distinct grains (shape and material): {}, each meshed and built once; the totals are the whole scene's",
            m.grains.len()
        );
    }
    if let Scope::Ranks(scene) = scope {
        println!(
            "on {} ranks: the grain table lists rank 0's grains; the totals are the whole scene's",
            scene.ranks
        );
    }
    println!(
        "{:<12} {:>10} {:>10} {:>9} {:>9} {:>10} {:>10}{}",
        "grain",
        "elements",
        "nodes",
        "facets",
        "min dih°",
        "max aspect",
        "min edge m",
        if copies.is_some() { "    copies" } else { "" }
    );
    // periodic images are copies of owned grains: listed and counted once
    let held = &m.grains[..m.owned_grains];
    for (gi, g) in held.iter().enumerate().take(20) {
        let q = &g.quality;
        println!(
            "{:<12} {:>10} {:>10} {:>9} {:>9.2} {:>10.2} {:>10.3e}{}",
            g.name,
            q.elements,
            q.nodes,
            q.surface_facets,
            q.min_dihedral_deg,
            q.max_aspect_ratio,
            q.min_edge,
            copies.map_or(String::new(), |c| format!(" {:>9}", c[gi]))
        );
    }
    let (mut grains, mut elements, mut nodes, mut phys) = (0, 0, 0, 0.0);
    for (gi, g) in held.iter().enumerate() {
        grains += copy(gi);
        elements += g.elements.len() * copy(gi);
        nodes += g.nodes.len() * copy(gi);
        phys += m.physical_mass[g.nodes.clone()].iter().sum::<f64>() * copy(gi) as f64;
    }
    let listed = held.len().min(20);
    if let Scope::Ranks(scene) = scope {
        (grains, elements, nodes, phys) = (
            scene.grains as usize,
            scene.elements as usize,
            scene.nodes as usize,
            scene.mass,
        );
        if grains > listed {
            println!(
                "... {} more grains ({} on rank 0)",
                grains - listed,
                held.len() - listed
            );
        }
    } else if held.len() > listed {
        println!("... {} more grains", held.len() - listed);
    }
    println!("totals: {grains} grains, {elements} elements, {nodes} nodes; mass {phys:.4e} kg");
    if let Some(c) = &m.periodic {
        let axes: String = (0..3)
            .filter(|&k| c.periodic[k])
            .map(|k| crate::scene::cell::AXES[k])
            .collect();
        println!(
            "periodic cell: {axes} periodic, box [{:.4e}, {:.4e}, {:.4e}] m from [{:.4e}, {:.4e}, {:.4e}] m; {} grain images mirrored on this rank",
            c.length0[0],
            c.length0[1],
            c.length0[2],
            c.min[0],
            c.min[1],
            c.min[2],
            m.grains.len() - m.owned_grains
        );
    }
    println!(
        "time step: stable {:.4e} s (element {}, safety {}), used {:.4e} s; {} steps for {:.4e} s",
        m.dt_stable,
        m.dt_critical_element,
        loaded.scene.simulation.dt_safety,
        m.dt,
        total_steps,
        loaded.scene.simulation.duration
    );
    let (scaled_elements, scaled_nodes) = match scope {
        Scope::Ranks(scene) => (
            scene.scaled_elements as usize,
            scene.scaled_contact_nodes as usize,
        ),
        _ => (m.scaled_elements, m.contact.stable_step.scaled_nodes),
    };
    if scaled_elements > 0 || scaled_nodes > 0 {
        // `mufe check` builds each distinct grain once: the scene's added mass is each
        // mesh's (element and contact-node scaling, read off the node masses) times its
        // copies, while the element count is the distinct meshes'.
        let (scaled, added) = match scope {
            Scope::Model => (
                format!("{scaled_elements} elements and {scaled_nodes} contact nodes scaled"),
                m.added_mass,
            ),
            Scope::Ranks(scene) => (
                format!("{scaled_elements} elements and {scaled_nodes} contact nodes scaled"),
                scene.added_mass,
            ),
            Scope::Representatives(_) => (
                format!(
                    "{scaled_elements} elements and {scaled_nodes} contact nodes of the distinct meshes scaled"
                ),
                m.grains
                    .iter()
                    .enumerate()
                    .map(|(gi, g)| {
                        let scaled: f64 = m.mass[g.nodes.clone()].iter().sum();
                        let physical: f64 = m.physical_mass[g.nodes.clone()].iter().sum();
                        (scaled - physical) * copy(gi) as f64
                    })
                    .sum(),
            ),
        };
        println!(
            "mass scaling: {scaled}, added mass {added:.4e} kg ({:.3}% of {phys:.4e} kg)",
            100.0 * added / phys,
        );
        if let Some(note) = heavy_scaling_damping_note(&loaded.scene, added / phys) {
            println!("{note}");
        }
    }
    let cm = &m.contact;
    if cm.active() {
        let st = &cm.stable_step;
        // a rank's arrays hold its ghosts' and periodic images' surfaces too: counted by
        // their owner
        let (surface_nodes, facets, max_penalty) = match scope {
            Scope::Ranks(scene) => (scene.surface_nodes, scene.facets, scene.max_penalty),
            Scope::Model => {
                let own = SceneCounts::owned_by(m);
                (own.surface_nodes, own.facets, st.max_penalty)
            }
            Scope::Representatives(_) => {
                (cm.node.len() as u64, cm.facet.len() as u64, st.max_penalty)
            }
        };
        if cm.grain_contact {
            println!(
                "contact: friction {}, penalty factor {} (max ε_n {:.3e} Pa/m), damping {} of critical, margin {:.3e} m, {} surface nodes, {} facets, {} walls",
                cm.friction,
                cm.penalty_factor,
                max_penalty,
                cm.damping,
                cm.margin,
                surface_nodes,
                facets,
                cm.walls.len()
            );
        } else {
            println!(
                "contact: {} walls (kinematic), margin {:.3e} m",
                cm.walls.len(),
                cm.margin
            );
        }
        if let Some(plan) = &solver.model.stages {
            print_stage_plan(plan, &cm.walls);
        }
        if st.contact_dt.is_finite() {
            let contact_added_mass = match scope {
                Scope::Ranks(scene) => scene.contact_added_mass,
                _ => st.added_mass,
            };
            println!(
                "contact stable step: {:.4e} s (node {}) vs {:.4e} s from elements alone (×{:.3}){}",
                st.contact_dt,
                st.critical_node.unwrap_or(0),
                st.element_dt,
                (st.contact_dt / st.element_dt).min(1.0),
                if scaled_nodes > 0 {
                    format!(
                        "; {} contact nodes mass-scaled, added {:.4e} kg{}",
                        scaled_nodes,
                        contact_added_mass,
                        if copies.is_some() { " (in the distinct meshes)" } else { "" }
                    )
                } else {
                    String::new()
                }
            );
        }
    }
    let per_element = estimate_memory_bytes(m) as f64 / m.num_elements().max(1) as f64;
    match scope {
        Scope::Ranks(scene) => println!(
            "memory estimate: {:.1} MiB over {} ranks, {:.1} MiB on rank 0 ({per_element:.0} bytes/element)",
            scene.memory_bytes as f64 / 1048576.0,
            scene.ranks,
            estimate_memory_bytes(m) as f64 / 1048576.0,
        ),
        _ => println!(
            "memory estimate: {:.1} MiB ({per_element:.0} bytes/element)",
            per_element * elements as f64 / 1048576.0,
        ),
    }
}

/// The closing lines of `mufe run`: stage table, throughput, energy balance, contact.
pub fn print_run_summary(summary: &RunSummary, solver: &Solver) {
    let e = &summary.energy;
    println!("{}", summary.timing_table);
    if let Some(line) = stage_times_by_rank(summary) {
        println!("{line}");
    }
    if let Some((whole, own)) = step_against_force_stage(&summary.stage_seconds_by_rank) {
        println!(
            "whole step = {whole:.2} × the internal-force stage of the slowest rank ({own:.2} × without the wait in sync)"
        );
    }
    if let Some(line) = narrow_phase_line(summary, solver) {
        println!("{line}");
    }
    println!(
        "done: {} steps to t = {:.6e} s in {:.2} s wall ({:.3e} element updates/s, all ranks)",
        summary.steps,
        summary.time,
        summary.wall_s,
        summary.elements as f64 * summary.steps_run as f64
            / solver.timers.total_seconds().max(1e-9)
    );
    let c = &summary.checkpoints;
    if c.written > 0 {
        println!(
            "checkpoints: {} written in {:.2} s; the last {:.1} MB in {:.3} s ({:.0} MB/s, {:.1} MB per million elements)",
            c.written,
            c.total_seconds,
            c.last_bytes as f64 / 1e6,
            c.last_seconds,
            c.last_bytes as f64 / 1e6 / c.last_seconds.max(1e-9),
            c.last_bytes as f64 / c.elements.max(1) as f64
        );
    }
    let stages = &solver.state.stages;
    if solver.model.stages.as_ref().is_some_and(|p| p.staged) {
        for (i, r) in stages.done.iter().enumerate() {
            let ke = summary.max_kinetic_ratio.get(i).copied().unwrap_or(0.0);
            println!("{}; max ALLKE/ALLIE {ke:.2e}", describe_stage(r));
        }
        if let Some(g) = summary.first_opening {
            println!(
                "first gap opening between initially touching grains {} and {}: t = {:.4e} s, axial strain {:.4e} (since the stage start; to one history interval)",
                g.a, g.b, g.time, g.axial_strain
            );
        }
        if !stages.finished {
            println!(
                "stages: ended in stage {} of {} at simulation.duration (or --max-steps)",
                stages.index + 1,
                solver.model.stages.as_ref().map_or(0, |p| p.stages.len())
            );
        }
    }
    // ½ v₋·M v₊ is the kinetic energy the leapfrog conserves exactly; it dips below zero
    // (by O((ωΔt)²) of the strain energy) when the fast modes dominate a block at rest.
    let kinetic_note = if e.kinetic < 0.0 {
        " (½ v(n−½)·M v(n+½), below 0 near rest: docs/THEORY.md, energy ledger)"
    } else {
        ""
    };
    println!(
        "energy: kinetic {:.4e} J{kinetic_note}, strain {:.4e} J (recoverable {:.4e} J, plastic {:.4e} J), friction {:.4e} J, external work {:.4e} J, damping {:.4e} J, balance error {:.2e} (relative)",
        e.kinetic,
        e.strain(),
        e.recoverable_strain,
        e.plastic_dissipation,
        e.friction_dissipation,
        e.external_work(),
        e.damping_dissipation(),
        e.relative_balance_error()
    );
    if solver.model.contact.active() {
        println!(
            "contact: {} points now, at most {}; max penetration {:.3e} m ({:.2e} × smallest surface edge); {} broad-phase rebuilds, skin now {:.3e} m; {:.1}% of step time in contact",
            summary.contacts_now,
            summary.max_contacts,
            summary.max_penetration,
            summary.max_penetration / solver.model.contact.min_edge.max(f64::MIN_POSITIVE),
            summary.rebuilds,
            solver.state.contact.stats.skin,
            100.0 * summary.contact_share
        );
    }
    if !summary.halo_bytes.is_empty() {
        let list = |i: usize| {
            let v: Vec<String> = summary
                .halo_bytes
                .iter()
                .map(|b| b[i].to_string())
                .collect();
            v.join(", ")
        };
        let (drift, limit) = summary.dormant_drift;
        println!(
            "halo: bytes sent per step by rank: mean {} (full exchanges at the checks and refreshes at rebuilds included), now {} (what contact reads), whole contact zones {}, whole ghost surfaces {}; ghost nodes outside the trimmed halo moved at most {drift:.3e} m between refreshes (limit {limit:.3e} m)",
            list(0),
            list(1),
            list(2),
            list(3),
        );
    }
    println!("results: {}", summary.results.display());
}

/// A note when mass scaling at least doubles the grains' mass and some stage damps
/// (docs/QUASI_STATIC.md). Heavy mass scaling slows the cell's rigid modes by
/// √(1 + added/physical mass), while mass-proportional damping acts on the scaled mass:
/// the same α then damps those modes that much more than in the unscaled scene (an
/// over-damped consolidation creeps).
fn heavy_scaling_damping_note(scene: &crate::scene::Scene, added_fraction: f64) -> Option<String> {
    let global = scene.simulation.damping;
    let alpha = if scene.stages.is_empty() {
        global
    } else {
        let per_stage = scene.stages.iter().map(|st| st.damping.unwrap_or(global));
        per_stage.fold(0.0_f64, f64::max)
    };
    if added_fraction < 1.0 || alpha <= 0.0 {
        return None;
    }
    let slowdown = (1.0 + added_fraction).sqrt();
    Some(format!(
        "note: mass damping {alpha:.3e} 1/s acts on the scaled mass ({:.1}× the grains'), whose rigid modes are {slowdown:.2}× slower: {:.3e} 1/s keeps the unscaled scene's damping ratio (docs/QUASI_STATIC.md)",
        1.0 + added_fraction,
        alpha / slowdown
    ))
}

/// One line per stage (its wall modes and end conditions) and per servo wall.
fn print_stage_plan(plan: &StagePlan, walls: &[crate::model::contact_layout::Wall]) {
    for (i, st) in plan.stages.iter().enumerate() {
        if plan.staged {
            let u = &st.until;
            let mut ends = vec![format!("max_time {:.3e} s", u.max_time)];
            if let Some((tol, hold)) = u.stress_held {
                ends.push(format!("stress held within {tol} for {hold:.3e} s"));
            }
            if let Some(e) = u.axial_strain {
                ends.push(format!("axial strain {e}"));
            }
            if let Some(f) = u.failure {
                let plateau = f
                    .plateau_strain
                    .map(|w| format!(" or no 1 % rise over {w} strain"))
                    .unwrap_or_default();
                ends.push(format!(
                    "failure (ratio {} below peak{plateau}) + {} strain",
                    f.drop, f.strain_margin
                ));
            }
            // the periodic cell's axes follow the walls in the plan
            let names = (walls.iter().map(|w| w.name.clone()))
                .chain(crate::scene::cell::AXES.map(|a| format!("cell {a}")));
            let modes: Vec<String> = (st.modes.iter().zip(names))
                .map(|(m, name)| match m {
                    WallMode::Prescribed => format!("{name} prescribed"),
                    WallMode::Fixed => format!("{name} fixed"),
                    WallMode::Velocity(v) => format!("{name} {v:.3e} m/s"),
                    WallMode::Servo { control, .. } => {
                        format!("{name} servo {:.4e} Pa", control.target_stress)
                    }
                })
                .collect();
            let mut body = String::new();
            if let Some(d) = st.damping {
                body += &format!("; damping {d:.3e} 1/s");
            }
            if let Some(g) = st.gravity {
                body += &format!("; gravity [{:.4e}, {:.4e}, {:.4e}] m/s²", g[0], g[1], g[2]);
            }
            println!(
                "stage {} '{}': {}{body}; ends at {}",
                i + 1,
                st.name,
                modes.join(", "),
                ends.join(" or ")
            );
        }
        for (m, w) in st.modes.iter().zip(walls) {
            if let WallMode::Servo {
                control: s,
                lattice_area,
            } = m
            {
                println!(
                    "  servo wall {}: {:.4e} Pa on {:.4e} m²{} (F* = {:.4e} N), stiffness {:.3e} N/m, τ = {:.3e} s (filter {:.3e} s), max speed {:.3e} m/s",
                    w.name,
                    s.target_stress,
                    s.area,
                    if *lattice_area { " at t = 0, then the current lattice span" } else { "" },
                    s.target_force,
                    s.stiffness,
                    s.time_constant,
                    s.filter_time,
                    s.max_speed
                );
            }
        }
    }
}

/// The finished stages as `/stages` of results.h5 holds them: the summary line and its
/// figures (times in s, ratios and strains dimensionless).
pub fn stage_attributes(done: &[StageRecord]) -> Vec<StageAttributes> {
    (done.iter().enumerate())
        .map(|(i, r)| {
            let mut numbers = vec![("start_time", r.start), ("end_time", r.end)];
            if let Some(p) = r.peak.filter(|p| p.ratio > 0.0) {
                numbers.extend([
                    ("peak_stress_ratio", p.ratio),
                    ("peak_time", p.time),
                    ("peak_axial_strain", p.axial_strain),
                ]);
            }
            if let Some(f) = r.failure {
                numbers.extend([
                    ("failure_stress_ratio", f.ratio),
                    ("failure_time", f.time),
                    ("failure_axial_strain", f.axial_strain),
                ]);
            }
            if let Some(residual) = r.residual {
                numbers.push(("residual_stress_ratio", residual));
            }
            StageAttributes {
                number: i as u64 + 1,
                name: r.name.clone(),
                text: vec![
                    ("ended_by", r.reason.describe().to_string()),
                    ("summary", describe_stage(r)),
                ],
                numbers,
            }
        })
        .collect()
}

/// One line for a finished stage: its span, why it ended, the peak stress ratio and
/// failure (time and axial strain since the stage start) when the cell measures them.
pub fn describe_stage(r: &StageRecord) -> String {
    let mut line = format!(
        "stage '{}' done: t = {:.4e} … {:.4e} s, ended by {}",
        r.name,
        r.start,
        r.end,
        r.reason.describe()
    );
    if let Some(p) = r.peak.filter(|p| p.ratio > 0.0) {
        line += &format!(
            "; peak σ1/σ3 = {:.4} at t = {:.4e} s, axial strain {:.4e}",
            p.ratio, p.time, p.axial_strain
        );
    }
    if let Some(f) = r.failure {
        line += &format!(
            "; failure detected at t = {:.4e} s, axial strain {:.4e} (σ1/σ3 = {:.4})",
            f.time, f.axial_strain, f.ratio
        );
    }
    if let Some(residual) = r.residual {
        line += &format!("; mean σ1/σ3 after it (residual) = {residual:.4}");
    }
    line
}

/// One line with every rank's time per step in each stage (ms), when there are several
/// ranks: the stage table is rank 0's, and load imbalance shows as one rank's wait.
fn stage_times_by_rank(summary: &RunSummary) -> Option<String> {
    let rows = &summary.stage_seconds_by_rank;
    if rows.len() < 2 || summary.steps_run == 0 {
        return None;
    }
    let per_step = 1e3 / summary.steps_run as f64;
    let cells: Vec<String> = (Stage::ALL.iter().enumerate())
        .filter(|&(i, _)| rows.iter().any(|row| row[i] * per_step >= 0.05))
        .map(|(i, st)| {
            let ms: Vec<String> = (rows.iter())
                .map(|row| format!("{:.1}", row[i] * per_step))
                .collect();
            format!("{} {}", st.name(), ms.join(" / "))
        })
        .collect();
    Some(format!("ms/step by rank (0 / 1 / …): {}", cells.join(", ")))
}

/// The narrow phase of this rank (rank 0 under MPI, like the stage table): its time per
/// step, the entries it evaluated per step, the cost of one entry, and that cost in
/// element updates of the same rank's force stage, a ratio that carries across machines
/// (what issue 14's whole-step measure turns on: docs/BENCHMARKS.md, sessions 64 and 71).
/// `None` when no entry was evaluated.
fn narrow_phase_line(summary: &RunSummary, solver: &Solver) -> Option<String> {
    let (ms, entries, us) = solver.scratch.contact.narrow.per_step()?;
    let forces = solver.timers.seconds(Stage::InternalForces);
    let updates = solver.model.owned_elements as f64 * summary.steps_run as f64;
    let in_updates = if forces > 0.0 && updates > 0.0 {
        format!(
            " = {:.0} element updates of the force stage",
            us * updates / (1e6 * forces)
        )
    } else {
        String::new()
    };
    let whose = if summary.stage_seconds_by_rank.len() > 1 {
        " on rank 0"
    } else {
        ""
    };
    Some(format!(
        "contact narrow phase{whose}: {ms:.3} ms/step, {entries:.0} entries evaluated per step, {us:.3} µs per entry{in_updates}"
    ))
}

/// The whole step (every stage, the wait included) over the internal-force stage of the
/// slowest rank, and the largest ratio of one rank's own work (its step less its `sync`
/// wait) to its own force stage: how much the rest of the step costs next to the
/// elements. `None` without steps or force-stage time.
fn step_against_force_stage(rows: &[[f64; Stage::ALL.len()]]) -> Option<(f64, f64)> {
    let (forces, sync) = (Stage::InternalForces as usize, Stage::Sync as usize);
    let slowest = rows.iter().map(|r| r[forces]).fold(0.0, f64::max);
    if slowest <= 0.0 {
        return None;
    }
    let step = rows
        .iter()
        .map(|r| r.iter().sum::<f64>())
        .fold(0.0, f64::max);
    let own = (rows.iter())
        .map(|r| (r.iter().sum::<f64>() - r[sync]) / r[forces].max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    Some((step / slowest, own))
}

#[cfg(test)]
mod tests {
    use super::heavy_scaling_damping_note;

    #[test]
    fn the_step_is_set_against_the_slowest_force_stage_and_the_wait_taken_out() {
        use super::step_against_force_stage;
        use crate::solver::timing::Stage;
        let row = |forces: f64, contact: f64, sync: f64| {
            let mut r = [0.0; Stage::ALL.len()];
            r[Stage::InternalForces as usize] = forces;
            r[Stage::Contact as usize] = contact;
            r[Stage::Sync as usize] = sync;
            r[Stage::Halo as usize] = 1.0;
            r
        };
        // rank 0 waits 20 for rank 1, whose force stage is the longer one: both steps are
        // 100 + 40 + 1 + their wait
        let rows = [row(80.0, 40.0, 21.0), row(100.0, 40.0, 1.0)];
        let (whole, own) = step_against_force_stage(&rows).unwrap();
        assert_eq!(whole, 142.0 / 100.0);
        assert_eq!(own, 121.0 / 80.0);
        assert_eq!(step_against_force_stage(&[row(0.0, 3.0, 0.0)]), None);
        assert_eq!(step_against_force_stage(&[]), None);
    }
    use crate::scene::parse_scene;

    const ENERGY_CELL: &str = include_str!("../../jobs/fcc/energy_plastic.toml");

    #[test]
    fn heavy_mass_scaling_suggests_the_damping_that_keeps_the_unscaled_ratio() {
        let loaded = parse_scene("energy_plastic.toml", ENERGY_CELL, &[]).unwrap();
        let alpha = loaded.scene.simulation.damping;
        let added = 33.6;
        let note = heavy_scaling_damping_note(&loaded.scene, added).expect("a note");
        let suggested = format!("{:.3e} 1/s keeps", alpha / (1.0_f64 + added).sqrt());
        assert!(note.contains(&suggested), "{note}");
        // light scaling (the thornton_walls cell: 39 %) leaves the damping alone
        assert!(heavy_scaling_damping_note(&loaded.scene, 0.39).is_none());
        // no stage damps (the consolidation stage undamped too): nothing to say
        let undamped = ["stages[0].damping=0.0".to_string()];
        let loaded = parse_scene("energy_plastic.toml", ENERGY_CELL, &undamped).unwrap();
        assert!(heavy_scaling_damping_note(&loaded.scene, added).is_none());
    }
}
