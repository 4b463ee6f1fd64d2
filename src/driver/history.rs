//! The `/history` series of a run: column definitions (names, units, Abaqus names),
//! one row per output step, and how each column combines over ranks.

use super::grain_motion::grain_motion;
use crate::boundary::stages::{StagePlan, WallMode};
use crate::domain::Domain;
use crate::energy::EnergyLedger;
use crate::io::results::HistoryColumn;
use crate::math::norm;
use crate::solver::Solver;

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
            None,
            "whole stress work of the grains: recoverable strain energy + plastic dissipation",
        ),
        HistoryColumn::new(
            "recoverable_strain_energy",
            "J",
            Some("ALLSE"),
            "elastic (recoverable) strain energy Σ V0 ψ(ε̃ᵉ)",
        ),
        HistoryColumn::new(
            "internal_energy",
            "J",
            Some("ALLIE"),
            "recoverable strain energy + plastic dissipation + contact penalty energy",
        ),
        HistoryColumn::new(
            "plastic_dissipation",
            "J",
            Some("ALLPD"),
            "plastic work Σ V0 T̃:Δεᵖ, accumulated per element at every step",
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
        HistoryColumn::new(
            "plastic_index",
            "1",
            None,
            "ALLPD / (ALLSE + ALLPD): share of the grains' stress work dissipated plastically",
        ),
        HistoryColumn::new(
            "friction_index",
            "1",
            None,
            "ALLFD / (ALLFD + ALLPD + ALLSE): share of friction in the energy taken up by grains and contacts",
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
    for w in servo_walls(solver) {
        let w = &cm.walls[w];
        for (what, units, desc) in [
            (
                "stress_target",
                "Pa",
                "target normal stress of the servo wall (this and the next two are 0 while the stage does not stress-control the wall)",
            ),
            (
                "stress",
                "Pa",
                "filtered normal force of the wall on the grains over the servo area (the cell's current lattice span for area_of)",
            ),
            (
                "stress_error",
                "1",
                "(stress − stress_target)/stress_target",
            ),
        ] {
            c.push(HistoryColumn::new(
                &format!("{}_{what}", w.name),
                units,
                None,
                desc,
            ));
        }
    }
    for (name, units, desc) in stage_columns(solver) {
        c.push(HistoryColumn::new(&name, units, None, desc));
    }
    if solver.model.periodic.is_some() {
        for (name, units, desc) in periodic_columns() {
            c.push(HistoryColumn::new(&name, units, None, desc));
        }
    }
    if cm.grain_contact {
        for (name, units, desc) in FABRIC_COLUMNS {
            c.push(HistoryColumn::new(name, units, None, desc));
        }
    }
    c
}

/// The last columns when grains touch grains (see `crate::contact::fabric`); the two
/// counts are filled in by the output after a gather over ranks.
pub const FABRIC_COLUMNS: [(&str, &str, &str); 3] = [
    (
        "grain_pair_contacts",
        "",
        "grain pairs in contact (any active contact point of either pass)",
    ),
    (
        "sliding_grain_pair_contacts",
        "",
        "grain pairs in gross sliding (every active point of the pair on the Coulomb cone)",
    ),
    (
        "mean_grain_rotation",
        "rad",
        "mean over grains of the angle of each grain's best-fitting rigid rotation since t = 0",
    ),
];

/// How each column of [`history_columns`] combines over ranks.
pub fn history_reductions(solver: &Solver) -> Vec<Reduce> {
    let mut k = vec![Reduce::Same, Reduce::Same];
    k.extend([Reduce::Sum; 9]);
    k.extend([Reduce::Derived; 2]);
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
    // from the wall forces already summed over ranks in the step
    let same = 3 * servo_walls(solver).count() + stage_columns(solver).len();
    k.extend(std::iter::repeat_n(Reduce::Same, same));
    if solver.model.periodic.is_some() {
        // lengths and the contact stress are global already; the rest are rank shares
        k.extend([Reduce::Same; 3 + 6]);
        k.extend([Reduce::Sum; 6 + 6 + 1]);
    }
    if solver.model.contact.grain_contact {
        // counts from rank 0 (zero elsewhere); each rank's share of the mean rotation
        k.extend([Reduce::Sum; FABRIC_COLUMNS.len()]);
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
        e.strain(),
        e.recoverable_strain,
        e.internal(),
        e.plastic_dissipation,
        e.friction_dissipation,
        e.external_work(),
        e.damping_dissipation(),
        e.total(),
        e.plastic_index(),
        e.friction_index(),
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
    if let Some(plan) = &solver.model.stages {
        push_stage_values(solver, plan, row);
    }
    if let (Some(cell), Some(c)) = (&solver.model.periodic, &s.cell) {
        push_periodic_values(solver, cell, c, row);
    }
    if solver.model.contact.grain_contact {
        let m = &solver.model;
        // every grain of the scene has an owner: the mean over ranks is the sum of shares
        let grains = s.partition.owner.len().max(1) as f64;
        let rotation_share: f64 = (0..m.owned_grains)
            .map(|g| norm(grain_motion(m, &s.x, g).rotation))
            .sum::<f64>()
            / grains;
        row.extend_from_slice(&[0.0, 0.0, rotation_share]);
    }
}

/// Stage, servo and cell values of a history row.
fn push_stage_values(solver: &Solver, plan: &StagePlan, row: &mut Vec<f64>) {
    let s = &solver.state;
    let p = &s.stages;
    let measure = plan.measure(&p.wall_displacements, &p.wall_forces);
    let stage = plan.current(p);
    for w in servo_walls(solver) {
        match (&stage.modes[w], &s.contact.walls[w].servo) {
            (mode @ WallMode::Servo { control, .. }, Some(servo)) => {
                let target = plan.target_force(w, mode, measure.as_ref());
                let area = target / control.target_stress;
                row.extend_from_slice(&[
                    control.target_stress,
                    servo.filtered_force / area,
                    (servo.filtered_force - target) / target,
                ]);
            }
            _ => row.extend_from_slice(&[0.0; 3]),
        }
    }
    if plan.staged {
        row.push((p.index.min(plan.stages.len() - 1) + 1) as f64);
    }
    if let Some(m) = measure {
        row.extend_from_slice(&m.stress);
        row.extend_from_slice(&m.stress_wall_to_wall);
        row.extend_from_slice(&m.strain);
        row.extend_from_slice(&[m.volumetric_strain, m.ratio, m.ratio_wall_to_wall]);
    }
}

/// Walls stress-controlled in some stage (wall indices).
fn servo_walls(solver: &Solver) -> impl Iterator<Item = usize> + '_ {
    let plan = solver.model.stages.as_ref();
    (0..solver.model.contact.walls.len()).filter(move |&w| {
        plan.is_some_and(|p| {
            (p.stages.iter()).any(|st| matches!(st.modes[w], WallMode::Servo { .. }))
        })
    })
}

/// The stage and cell columns (after the servo columns): (name, units, description).
fn stage_columns(solver: &Solver) -> Vec<(String, &'static str, &'static str)> {
    let mut c = Vec::new();
    let Some(plan) = &solver.model.stages else {
        return c;
    };
    if plan.staged {
        c.push((
            "stage".to_string(),
            "",
            "number of the stage in force (1 = the first [[stages]] entry)",
        ));
    }
    if plan.cell.is_some() {
        for (what, units, desc) in [
            ("sigma", "Pa", "mean normal force of the axis' two walls over the lattice-span area (between outer sphere centres: wall to wall − 2R on the other two axes), compression positive"),
            ("sigma_wall_to_wall", "Pa", "the same force over the wall-to-wall area"),
            ("strain", "1", "nominal strain of the wall box since t = 0, (L0 − L)/L0, compression positive"),
        ] {
            for axis in ["x", "y", "z"] {
                let name = match what.split_once('_') {
                    Some((head, tail)) => format!("{head}_{axis}_{tail}"),
                    None => format!("{what}_{axis}"),
                };
                c.push((name, units, desc));
            }
        }
        c.push((
            "volumetric_strain".into(),
            "1",
            "1 − V/V0 of the wall box, compression positive",
        ));
        c.push(("stress_ratio".into(), "1", "σ_axial / mean lateral σ on the lattice-span areas (axial = the axis of the moving walls; 0 while the lateral walls carry no load, or less than 1e-3 of the axial stress)"));
        c.push((
            "stress_ratio_wall_to_wall".into(),
            "1",
            "the same ratio on the wall-to-wall areas",
        ));
    }
    c
}

/// Tensor components in the order of the element stress fields.
const COMPONENTS: [(&str, usize); 6] = [
    ("xx", 0),
    ("yy", 4),
    ("zz", 8),
    ("yz", 5),
    ("xz", 2),
    ("xy", 1),
];

/// The periodic cell's columns: (name, units, description).
fn periodic_columns() -> Vec<(String, &'static str, &'static str)> {
    let mut c = Vec::new();
    for axis in crate::scene::cell::AXES {
        c.push((
            format!("cell_length_{axis}"),
            "m",
            "edge length of the periodic cell",
        ));
    }
    for (what, desc) in [
        ("cell_contact_stress", "homogenised stress of the cell, contact part (Love–Weber): Σ f ⊗ l / V over contact points, l the branch vector between grain centres with the periodic image shift, compression positive; the servo holds its diagonal"),
        ("cell_kinetic_stress", "homogenised stress of the cell, kinetic part: Σ m v′ ⊗ v′ / V, v′ each grain's velocity relative to the cell's homogeneous flow; σ = contact + kinetic"),
        ("cell_grain_stress", "volume average over the cell of the grains' Cauchy stress, −Σ V_e σ_e / V, compression positive: equals the Love–Weber stress in equilibrium"),
    ] {
        for (comp, _) in COMPONENTS {
            c.push((format!("{what}_{comp}"), "Pa", desc));
        }
    }
    c.push((
        "cell_work".into(),
        "J",
        "work of the periodic cell on the grains (part of ALLWK): Σ f·(s ∘ L̇) over contacts with images",
    ));
    c
}

/// Values of [`periodic_columns`]: this rank's shares where they are sums.
fn push_periodic_values(
    solver: &Solver,
    cell: &crate::model::periodic::PeriodicCell,
    c: &crate::solver::periodic::CellState,
    row: &mut Vec<f64>,
) {
    let m = &solver.model;
    let s = &solver.state;
    let kin = s.cell_kinematics(m);
    let volume: f64 = kin.length.iter().product();
    row.extend_from_slice(&kin.length);
    row.extend(COMPONENTS.map(|(_, i)| c.contact_stress[i]));
    let mut kinetic = [0.0; 9];
    for g in &m.grains[..m.owned_grains] {
        let (mut mass, mut x, mut v) = (0.0, [0.0; 3], [0.0; 3]);
        for n in g.nodes.clone() {
            mass += m.mass[n];
            for k in 0..3 {
                x[k] += m.mass[n] * s.x[n][k];
                v[k] += m.mass[n] * s.v[n][k];
            }
        }
        let flow = |k: usize| kin.rate[k] / kin.length[k] * (x[k] / mass - cell.min[k]);
        let dv = [0, 1, 2].map(|k| v[k] / mass - flow(k));
        for i in 0..3 {
            for j in 0..3 {
                kinetic[3 * i + j] += mass * dv[i] * dv[j] / volume;
            }
        }
    }
    row.extend(COMPONENTS.map(|(_, i)| kinetic[i]));
    let mut grains = [0.0; 9];
    for e in 0..m.owned_elements {
        let (f, r) = crate::solver::element_response(m, &s.x, &s.plastic, e);
        let sigma = crate::material::cauchy_from_first_piola(&r.first_piola, &f);
        let jacobian = crate::math::det3(&f);
        let v = jacobian * m.tet_reference.get(e).volume;
        for i in 0..9 {
            grains[i] -= v * sigma[i] / volume;
        }
    }
    row.extend(COMPONENTS.map(|(_, i)| grains[i]));
    row.push(c.work.work);
}

/// How a history column combines over ranks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reduce {
    /// Identical on every rank (time, wall displacement).
    Same,
    Sum,
    Max,
    /// A ratio of other columns, recomputed from their reduced values.
    Derived,
}

/// Reduces a history row in place. All ranks must call.
pub fn reduce_row(domain: &Domain, kinds: &[Reduce], row: &mut [f64]) {
    if domain.size() == 1 {
        return;
    }
    let mut sums: Vec<f64> = kinds
        .iter()
        .zip(row.iter())
        .filter(|(k, _)| **k == Reduce::Sum)
        .map(|(_, v)| *v)
        .collect();
    let mut maxes: Vec<f64> = kinds
        .iter()
        .zip(row.iter())
        .filter(|(k, _)| **k == Reduce::Max)
        .map(|(_, v)| *v)
        .collect();
    domain.sum_in_place(&mut sums);
    domain.max_in_place(&mut maxes);
    let (mut s, mut m) = (sums.into_iter(), maxes.into_iter());
    for (k, v) in kinds.iter().zip(row.iter_mut()) {
        match k {
            Reduce::Sum => *v = s.next().unwrap_or(*v),
            Reduce::Max => *v = m.next().unwrap_or(*v),
            Reduce::Same | Reduce::Derived => {}
        }
    }
    derive_indices(row);
}

/// Positions of energy columns (see [`history_columns`]).
pub const KINETIC: usize = 2;
pub const INTERNAL: usize = 5;
const RECOVERABLE: usize = 4;
const PLASTIC: usize = 6;
const FRICTION: usize = 7;
const PLASTIC_INDEX: usize = 11;
const FRICTION_INDEX: usize = 12;

/// Recomputes the energy indices of a row from its (reduced) energy columns, with the
/// formulas of [`EnergyLedger::plastic_index`] and [`EnergyLedger::friction_index`].
fn derive_indices(row: &mut [f64]) {
    let ledger = EnergyLedger {
        recoverable_strain: row[RECOVERABLE],
        plastic_dissipation: row[PLASTIC],
        friction_dissipation: row[FRICTION],
        ..EnergyLedger::default()
    };
    row[PLASTIC_INDEX] = ledger.plastic_index();
    row[FRICTION_INDEX] = ledger.friction_index();
}

/// The energy ledger summed over ranks (each rank's ledger covers its owned grains). All
/// ranks must call.
pub fn global_ledger(domain: &Domain, e: &EnergyLedger) -> EnergyLedger {
    let mut v = e.to_sums();
    if domain.size() > 1 {
        domain.sum_in_place(&mut v);
    }
    EnergyLedger::from_sums(&v, e.initial_total.is_some())
}
