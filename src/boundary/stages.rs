//! Wall control over a run: the stage plan (each stage's wall modes and end condition),
//! the box of walls as a measuring cell (stresses on the lattice span, strains, stress
//! ratio), and the stage progress carried in the solver state.
//!
//! Every wall driven by state (a servo wall, or any wall of a staged scene) moves along
//! its normal by the displacement s in its `ServoState`; a stage sets its speed for the
//! next step: 0 (fixed), a constant (velocity, strain rate × L0) or the servo law. All
//! inputs are global (wall forces summed over ranks), so every rank takes the same
//! decisions at the same step without further communication.

use super::servo::{servo_control, ServoControl, ServoState};
use crate::scene::cell::PeriodicBox;
use crate::scene::packing::PackingSpec;
use crate::scene::stages::{wall_pairs, StageSpec, WallModeSpec};
use crate::scene::{normal_axis, Scene, ServoSpec, WallSpec};
use serde::{Deserialize, Serialize};

/// The stress ratio σ1/σ3 is measured only while the mean lateral stress exceeds this
/// part of the axial stress (–); below it the history's `stress_ratio` is 0 (undefined).
/// A cohesionless packing fails below 2(1+μ)/(1−μ) (Thornton), 400 even at μ = 0.99, so a
/// ratio above 1000 is a lateral wall grazed by a node, not a measurement.
pub const RATIO_LATERAL_FLOOR: f64 = 1.0e-3;

/// How one wall moves during a stage.
#[derive(Debug, Clone, PartialEq)]
pub enum WallMode {
    /// By its prescribed history (walls of an unstaged scene without servo).
    Prescribed,
    Fixed,
    /// Constant speed towards the grains (m/s).
    Velocity(f64),
    /// Stress control; with `lattice_area` the target force is σ × the current
    /// lattice-span area of the cell, so that the servo holds the σ the cell measures.
    Servo {
        control: ServoControl,
        lattice_area: bool,
    },
}

/// End conditions of a stage (see `crate::scene::stages::UntilSpec`).
#[derive(Debug, Clone, PartialEq)]
pub struct Until {
    pub max_time: f64,
    /// (tolerance, hold time in s).
    pub stress_held: Option<(f64, f64)>,
    pub axial_strain: Option<f64>,
    pub failure: Option<FailureRule>,
    /// (wall index, normal force in N, hold time in s).
    pub wall_force: Option<(usize, f64, f64)>,
}

/// When a stage counts the specimen as failed (`crate::scene::stages::FailureSpec`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FailureRule {
    /// Relative drop below the peak ratio (–).
    pub drop: f64,
    /// Axial strain run on after failure (–).
    pub strain_margin: f64,
    /// Axial strain without a rise of [`PLATEAU_RISE`] that counts as failure (–).
    pub plateau_strain: Option<f64>,
}

/// Relative rise of the stress ratio that restarts the plateau window: 1 % over the window
/// (2e-5 strain in the FCC cells, ~1/100 of the slope before the peak) is flat; after the
/// sliding peak a walled cell creeps up by ~0.1 % per 1e-5 strain as its boundary spheres
/// roll, which would otherwise keep the stage going to its time limit.
pub const PLATEAU_RISE: f64 = 1e-2;

#[derive(Debug, Clone, PartialEq)]
pub struct Stage {
    pub name: String,
    /// Mode of every wall, in scene order.
    pub modes: Vec<WallMode>,
    pub until: Until,
    /// Some wall moves at a prescribed speed: the servo walls add integral action to
    /// follow the specimen's steady deformation (`crate::boundary::servo`).
    pub strains: bool,
    /// Mass-proportional damping during the stage (1/s), replacing `simulation.damping`.
    pub damping: Option<f64>,
    /// Gravity during the stage (m/s²), replacing `simulation.gravity`.
    pub gravity: Option<[f64; 3]>,
}

/// The specimen's box: a closed box of walls (one opposite pair per axis), or a cell
/// periodic along every axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// (lower wall, upper wall) of each axis: normals +eₖ and −eₖ (walls only).
    pub pairs: [(usize, usize); 3],
    /// Periodic cell: index of its x axis among the plan's walls (y, z follow); the box
    /// is the cell itself and the forces are its homogenised stress × face area.
    pub periodic_first: Option<usize>,
    /// Sphere radius R of the packing: the lattice span is wall to wall − 2R.
    pub radius: Option<f64>,
    /// Wall-to-wall distances at t = 0 (m).
    pub distance0: [f64; 3],
}

/// The static wall-control plan of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct StagePlan {
    pub stages: Vec<Stage>,
    /// Whether the scene listed `[[stages]]` (otherwise one implicit stage).
    pub staged: bool,
    /// Each wall's point at t = 0 and unit normal.
    pub walls: Vec<([f64; 3], [f64; 3])>,
    pub cell: Option<Cell>,
    /// Axis of σ1 in the stress ratio: the axis of the moving walls of the last stage
    /// that has some (z otherwise).
    pub axial: usize,
    /// Low-pass filter time of the wall forces the cell is measured with (s): the
    /// servos' (τ/32 of the fastest loop), 0 without servo walls. The raw kinematic wall
    /// force jumps from step to step (single nodes arrested), and a stage must not end on
    /// such a spike.
    pub filter_time: f64,
}

/// Cell measurements at one step (stresses compression positive, Pa; strains –).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CellMeasure {
    /// Lattice-span area across each axis: the product of the other two axes' wall
    /// distances less 2R (m²); the wall-to-wall area without a packing.
    pub area: [f64; 3],
    /// Mean normal force of each axis' two walls over `area`.
    pub stress: [f64; 3],
    /// The same over the wall-to-wall area.
    pub stress_wall_to_wall: [f64; 3],
    /// Wall-to-wall distance (m).
    pub distance: [f64; 3],
    /// Nominal strain of each axis since t = 0, (L0 − L)/L0.
    pub strain: [f64; 3],
    /// 1 − V/V0 of the wall box.
    pub volumetric_strain: f64,
    /// σ_axial / mean lateral σ, lattice span and wall to wall.
    pub ratio: f64,
    pub ratio_wall_to_wall: f64,
}

/// Why a stage ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum StageEnd {
    MaxTime,
    StressHeld,
    AxialStrain,
    Failure,
    WallForce,
}

impl StageEnd {
    pub fn describe(self) -> &'static str {
        match self {
            StageEnd::MaxTime => "max_time reached",
            StageEnd::StressHeld => "stress held",
            StageEnd::AxialStrain => "axial strain reached",
            StageEnd::Failure => "failure + margin",
            StageEnd::WallForce => "wall force reached",
        }
    }
}

/// A finished stage, as reported at the end of the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageRecord {
    pub name: String,
    pub start: f64,
    pub end: f64,
    pub reason: StageEnd,
    /// Peak stress ratio in the stage with its time and axial strain (since the stage
    /// start), when the cell measures one.
    pub peak: Option<RatioPoint>,
    /// Time and axial strain at which failure was detected.
    pub failure: Option<RatioPoint>,
    /// Mean σ1/σ3 over the steps from failure detection to the stage's end (the strain
    /// margin): the post-failure residual. Its loading-rate sensitivity is far below the
    /// peak's on open-faced blocks (docs/QUASI_STATIC.md).
    #[serde(default)]
    pub residual: Option<f64>,
}

/// A point of the stress-ratio curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RatioPoint {
    pub ratio: f64,
    pub time: f64,
    pub axial_strain: f64,
}

/// Where the run is in its stages (part of the solver state).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StageProgress {
    pub index: usize,
    pub started_at: f64,
    /// Wall-to-wall distances when the stage started (m).
    pub distance_at_start: [f64; 3],
    /// Since when every servo wall is within tolerance.
    pub held_since: Option<f64>,
    /// Since when the `wall_force` wall carries its force.
    #[serde(default)]
    pub force_since: Option<f64>,
    pub peak: Option<RatioPoint>,
    pub failure: Option<RatioPoint>,
    /// Last point where the ratio rose by [`PLATEAU_RISE`] over the previous such point.
    #[serde(default)]
    pub rising: Option<RatioPoint>,
    /// Σ σ1/σ3 and the number of steps since failure was detected (for
    /// [`StageRecord::residual`]).
    #[serde(default)]
    pub after_failure: (f64, u64),
    /// All stages done: the run stops.
    pub finished: bool,
    /// Normal force of every wall at the last step, summed over ranks and low-pass
    /// filtered over `StagePlan::filter_time` (N).
    pub wall_forces: Vec<f64>,
    /// Wall displacements at that step (m).
    pub wall_displacements: Vec<[f64; 3]>,
    pub done: Vec<StageRecord>,
}

impl StagePlan {
    /// The plan of a scene: its `[[stages]]`, or, when it has servo walls, one implicit
    /// stage with the walls' own settings; `None` when no wall is driven by state.
    pub fn build(scene: &Scene) -> Option<Self> {
        let staged = !scene.stages.is_empty();
        if !staged && scene.walls.iter().all(|w| w.servo.is_none()) {
            return None;
        }
        let walls: Vec<([f64; 3], [f64; 3])> = scene
            .walls
            .iter()
            .map(|w| {
                let l = w.normal.iter().map(|c| c * c).sum::<f64>().sqrt();
                (w.point, w.normal.map(|c| c / l))
            })
            .collect();
        let mut walls = walls;
        let periodic = PeriodicBox::of_scene(scene);
        let first_axis = walls.len();
        if let Some(c) = &periodic {
            // the cell's axes as walls on its upper faces, pushing along −eₖ
            for k in 0..3 {
                let mut normal = [0.0; 3];
                normal[k] = -1.0;
                let mut point = c.min;
                point[k] += c.length0[k];
                walls.push((point, normal));
            }
        }
        let pairs = wall_pairs(scene);
        let cell = match (pairs, &periodic) {
            (_, Some(c)) if c.periodic.iter().all(|&p| p) => Some(Cell {
                pairs: [(first_axis, first_axis); 3],
                periodic_first: Some(first_axis),
                radius: None,
                distance0: c.length0,
            }),
            ([Some(x), Some(y), Some(z)], _) => {
                let pairs = [x, y, z];
                Some(Cell {
                    pairs,
                    periodic_first: None,
                    radius: cell_packing(scene).map(|p| p.sphere.radius),
                    distance0: [0, 1, 2].map(|k| walls[pairs[k].1].0[k] - walls[pairs[k].0].0[k]),
                })
            }
            _ => None,
        };
        let lattice_area = |spec: &crate::scene::ServoSpec| {
            spec.area_of.is_some() && cell.as_ref().is_some_and(|c| c.radius.is_some())
        };
        let stages = if staged {
            scene
                .stages
                .iter()
                .map(|st| build_stage(scene, st, &walls, &lattice_area))
                .collect()
        } else {
            vec![Stage {
                name: "run".into(),
                modes: (scene.walls.iter())
                    .map(|w| match &w.servo {
                        Some(s) => WallMode::Servo {
                            control: servo_control(scene, w, s),
                            lattice_area: lattice_area(s),
                        },
                        None => WallMode::Prescribed,
                    })
                    .chain((first_axis..walls.len()).map(|_| WallMode::Fixed))
                    .collect(),
                strains: false,
                damping: None,
                gravity: None,
                until: Until {
                    max_time: f64::INFINITY,
                    stress_held: None,
                    axial_strain: None,
                    failure: None,
                    wall_force: None,
                },
            }]
        };
        let axial = stages
            .iter()
            .rev()
            .find_map(|st: &Stage| {
                st.modes
                    .iter()
                    .position(|m| matches!(m, WallMode::Velocity(_)))
                    .and_then(|w| normal_axis(walls[w].1))
            })
            .unwrap_or(2);
        let filter_time = stages
            .iter()
            .flat_map(|st| &st.modes)
            .filter_map(|m| match m {
                WallMode::Servo { control, .. } => Some(control.filter_time),
                _ => None,
            })
            .fold(f64::INFINITY, f64::min);
        Some(Self {
            stages,
            staged,
            walls,
            cell,
            axial,
            filter_time: if filter_time.is_finite() {
                filter_time
            } else {
                0.0
            },
        })
    }

    /// Whether wall `w` moves by its state (servo or staged) rather than a history.
    pub fn drives_wall(&self, w: usize) -> bool {
        self.staged || matches!(self.stages[0].modes[w], WallMode::Servo { .. })
    }

    /// The first state of the progress (before step 0).
    pub fn start(&self) -> StageProgress {
        StageProgress {
            distance_at_start: self.cell.as_ref().map_or([0.0; 3], |c| c.distance0),
            wall_forces: vec![0.0; self.walls.len()],
            wall_displacements: vec![[0.0; 3]; self.walls.len()],
            ..Default::default()
        }
    }

    /// The stage in force (the last one once all are done).
    pub fn current(&self, p: &StageProgress) -> &Stage {
        &self.stages[p.index.min(self.stages.len() - 1)]
    }

    /// Cell measurements from wall displacements `u` (m) and normal forces `f` (N).
    pub fn measure(&self, u: &[[f64; 3]], f: &[f64]) -> Option<CellMeasure> {
        let c = self.cell.as_ref()?;
        let distance = [0, 1, 2].map(|k| match c.periodic_first {
            Some(first) => c.distance0[k] + u[first + k][k],
            None => {
                let (lo, hi) = c.pairs[k];
                (self.walls[hi].0[k] + u[hi][k]) - (self.walls[lo].0[k] + u[lo][k])
            }
        });
        let lattice = distance.map(|d| d - 2.0 * c.radius.unwrap_or(0.0));
        let force = [0, 1, 2].map(|k| match c.periodic_first {
            Some(first) => f[first + k],
            None => 0.5 * (f[c.pairs[k].0] + f[c.pairs[k].1]),
        });
        let across = |l: &[f64; 3], k: usize| l[(k + 1) % 3] * l[(k + 2) % 3];
        let area = [0, 1, 2].map(|k| across(&lattice, k));
        let stress = [0, 1, 2].map(|k| force[k] / area[k]);
        let stress_wall_to_wall = [0, 1, 2].map(|k| force[k] / across(&distance, k));
        let a = self.axial;
        // undefined (0) until the lateral walls carry a measurable load: a lateral wall
        // grazed by one node gives σ3 ~ 1e-60 Pa and a ratio of 1e60
        let ratio_of = |s: &[f64; 3]| {
            let lateral = 0.5 * (s[(a + 1) % 3] + s[(a + 2) % 3]);
            if lateral > RATIO_LATERAL_FLOOR * s[a].abs() && lateral > 0.0 {
                s[a] / lateral
            } else {
                0.0
            }
        };
        Some(CellMeasure {
            area,
            stress,
            stress_wall_to_wall,
            distance,
            strain: [0, 1, 2].map(|k| 1.0 - distance[k] / c.distance0[k]),
            volumetric_strain: 1.0
                - distance.iter().product::<f64>() / c.distance0.iter().product::<f64>(),
            ratio: ratio_of(&stress),
            ratio_wall_to_wall: ratio_of(&stress_wall_to_wall),
        })
    }

    /// Target force (N) of servo wall `w` in mode `mode` with the cell as measured.
    pub fn target_force(&self, w: usize, mode: &WallMode, m: Option<&CellMeasure>) -> f64 {
        match (mode, m) {
            (
                WallMode::Servo {
                    control,
                    lattice_area: true,
                },
                Some(m),
            ) => control.target_stress * m.area[normal_axis(self.walls[w].1).unwrap_or(2)],
            (WallMode::Servo { control, .. }, _) => control.target_force,
            _ => 0.0,
        }
    }

    /// After the wall forces of step n (`forces`, summed over ranks, every wall; the
    /// walls' displacements at t_n already in `p.wall_displacements`): moves every
    /// state-driven wall (`kinematics`, in wall order) to t_{n+1}, sets its next speed
    /// from the stage's mode, and checks the stage's end at t_{n+1}.
    pub fn advance<'a>(
        &self,
        p: &mut StageProgress,
        kinematics: impl Iterator<Item = &'a mut Option<ServoState>>,
        forces: &[f64],
        t_next: f64,
        dt: f64,
    ) {
        let keep = dt / (self.filter_time + dt);
        for (filtered, &f) in p.wall_forces.iter_mut().zip(forces) {
            *filtered += keep * (f - *filtered);
        }
        let measure = self.measure(&p.wall_displacements, &p.wall_forces);
        let stage = self.current(p);
        let mut all_held = true;
        for (w, (mode, s)) in stage.modes.iter().zip(kinematics).enumerate() {
            let Some(s) = s else { continue };
            match mode {
                WallMode::Prescribed | WallMode::Fixed => s.move_on(dt, 0.0),
                WallMode::Velocity(v) => s.move_on(dt, *v),
                WallMode::Servo { control, .. } => {
                    let target = self.target_force(w, mode, measure.as_ref());
                    control.advance_to(s, forces[w], target, stage.strains, dt);
                    if let Some((tol, _)) = stage.until.stress_held {
                        all_held &= (s.filtered_force - target).abs() <= tol * target;
                    }
                }
            }
        }
        if p.finished {
            return;
        }
        let axial = measure.map(|m| (self.stage_axial_strain(p, &m), m.ratio));
        let until = &stage.until;
        let mut end = None;
        if let Some((_, hold)) = until.stress_held {
            if all_held {
                let since = *p.held_since.get_or_insert(t_next);
                if t_next - since >= hold {
                    end = Some(StageEnd::StressHeld);
                }
            } else {
                p.held_since = None;
            }
        }
        if let Some((w, force, hold)) = until.wall_force {
            if p.wall_forces.get(w).is_some_and(|&f| f >= force) {
                let since = *p.force_since.get_or_insert(t_next);
                if t_next - since >= hold {
                    end = Some(StageEnd::WallForce);
                }
            } else {
                p.force_since = None;
            }
        }
        if let Some((strain, ratio)) = axial {
            let point = RatioPoint {
                ratio,
                time: t_next,
                axial_strain: strain,
            };
            if p.peak.is_none_or(|pk| ratio > pk.ratio) {
                p.peak = Some(point);
            }
            if until.axial_strain.is_some_and(|e| strain >= e) {
                end = Some(StageEnd::AxialStrain);
            }
            if p.rising
                .is_none_or(|r| ratio > r.ratio * (1.0 + PLATEAU_RISE))
            {
                p.rising = Some(point);
            }
            if let Some(rule) = until.failure {
                let peak = p.peak.map_or(0.0, |pk| pk.ratio);
                let dropped = peak > 0.0 && ratio < (1.0 - rule.drop) * peak;
                let stalled = rule.plateau_strain.is_some_and(|w| {
                    p.rising
                        .is_some_and(|r| peak > 0.0 && strain >= r.axial_strain + w)
                });
                if p.failure.is_none() && (dropped || stalled) {
                    p.failure = Some(point);
                }
                if p.failure.is_some() {
                    p.after_failure.0 += ratio;
                    p.after_failure.1 += 1;
                }
                if p.failure
                    .is_some_and(|f| strain >= f.axial_strain + rule.strain_margin)
                {
                    end = Some(StageEnd::Failure);
                }
            }
        }
        if end.is_none() && t_next - p.started_at >= until.max_time * (1.0 - 1e-12) {
            end = Some(StageEnd::MaxTime);
        }
        if let Some(reason) = end {
            p.done.push(StageRecord {
                name: stage.name.clone(),
                start: p.started_at,
                end: t_next,
                reason,
                // a peak ratio means something in a stage that shears the cell to a strain
                // or to failure, not while a lid approaches or grains settle
                peak: p.peak.filter(|_| {
                    axial.is_some()
                        && stage.strains
                        && (until.axial_strain.is_some() || until.failure.is_some())
                }),
                failure: p.failure,
                residual: (p.after_failure.1 > 0)
                    .then(|| p.after_failure.0 / p.after_failure.1 as f64),
            });
            p.index += 1;
            p.finished = p.index >= self.stages.len();
            p.started_at = t_next;
            if let Some(m) = measure {
                p.distance_at_start = m.distance;
            }
            p.held_since = None;
            p.force_since = None;
            p.peak = None;
            p.failure = None;
            p.rising = None;
            p.after_failure = (0.0, 0);
        }
    }

    /// What the current stage waits for, for the progress line; `None` when it ends only
    /// on its time or strain cap, which [`Self::stage_fraction`] tracks. A stage that
    /// ends on a condition cannot know when it will be met: its fraction (and an ETA
    /// from it) measures the cap only, and this says how far the condition is.
    pub fn waiting_on(&self, p: &StageProgress, t: f64) -> Option<String> {
        let until = &self.current(p).until;
        if let Some(rule) = until.failure {
            let m = self.measure(&p.wall_displacements, &p.wall_forces)?;
            let strain = self.stage_axial_strain(p, &m);
            return Some(match (p.failure, p.peak) {
                (Some(f), _) => format!(
                    "failed at axial strain {:.2e}, margin {:.0} % run",
                    f.axial_strain,
                    100.0 * ((strain - f.axial_strain) / rule.strain_margin).clamp(0.0, 1.0)
                ),
                (None, Some(pk)) => format!(
                    "σ1/σ3 {:.3}, peak {:.3} at axial strain {:.2e}",
                    m.ratio, pk.ratio, pk.axial_strain
                ),
                (None, None) => format!("σ1/σ3 {:.3}", m.ratio),
            });
        }
        if let Some((tol, hold)) = until.stress_held {
            return Some(match p.held_since {
                Some(since) => format!(
                    "servos within {:.0} % for {:.2e} of {:.2e} s",
                    100.0 * tol,
                    t - since,
                    hold
                ),
                None => format!("servos not yet within {:.0} %", 100.0 * tol),
            });
        }
        if let Some((w, force, hold)) = until.wall_force {
            let now = p.wall_forces.get(w).copied().unwrap_or(0.0);
            return Some(match p.force_since {
                Some(since) => format!("wall force held {:.2e} of {:.2e} s", t - since, hold),
                None => format!("wall force {now:.3e} of {force:.3e} N"),
            });
        }
        None
    }

    /// Nominal axial strain since the current stage began (compression positive).
    pub fn stage_axial_strain(&self, p: &StageProgress, m: &CellMeasure) -> f64 {
        1.0 - m.distance[self.axial] / p.distance_at_start[self.axial]
    }

    /// Fraction (0..1) of the current stage done, by its time or strain bound.
    pub fn stage_fraction(&self, p: &StageProgress, t: f64) -> f64 {
        let until = &self.current(p).until;
        let by_time = (t - p.started_at) / until.max_time;
        let by_strain = match (
            until.axial_strain,
            self.measure(&p.wall_displacements, &p.wall_forces),
        ) {
            (Some(e), Some(m)) => self.stage_axial_strain(p, &m) / e,
            _ => 0.0,
        };
        by_time.max(by_strain).clamp(0.0, 1.0)
    }
}

/// The packing the servo areas refer to (the periodic cell's packing, else the first
/// `area_of` in the scene's walls or stages), or the first packing: its spheres set the
/// cell's lattice span, grain size and density.
fn cell_packing(scene: &Scene) -> Option<&PackingSpec> {
    if let Some(name) = scene.cell.as_ref().and_then(|c| c.packing.as_ref()) {
        return scene.packings.iter().find(|p| &p.name == name);
    }
    let named = scene
        .walls
        .iter()
        .filter_map(|w| w.servo.as_ref())
        .chain(scene.stages.iter().flat_map(|st| {
            st.walls.values().filter_map(|m| match m {
                WallModeSpec::Servo(s) => Some(s),
                _ => None,
            })
        }))
        .find_map(|s| s.area_of.as_ref());
    match named {
        Some(name) => scene.packings.iter().find(|p| &p.name == name),
        None => scene.packings.first(),
    }
}

fn build_stage(
    scene: &Scene,
    st: &StageSpec,
    walls: &[([f64; 3], [f64; 3])],
    lattice_area: &dyn Fn(&crate::scene::ServoSpec) -> bool,
) -> Stage {
    let modes: Vec<WallMode> = scene
        .walls
        .iter()
        .enumerate()
        .map(|(w, wall)| match st.walls.get(&wall.name) {
            None | Some(WallModeSpec::Fixed) => WallMode::Fixed,
            Some(WallModeSpec::Velocity(v)) => WallMode::Velocity(*v),
            Some(WallModeSpec::StrainRate(r)) => {
                WallMode::Velocity(r * opposite_distance(walls, w))
            }
            Some(WallModeSpec::InertialNumber(i)) => WallMode::Velocity(
                strain_rate_of_inertial_number(scene, st, *i) * opposite_distance(walls, w),
            ),
            Some(WallModeSpec::Servo(s)) => WallMode::Servo {
                control: servo_control(scene, wall, s),
                lattice_area: lattice_area(s),
            },
        })
        .chain(cell_axis_modes(scene, st))
        .collect();
    let u = &st.until;
    let tau = modes
        .iter()
        .filter_map(|m| match m {
            WallMode::Servo { control, .. } => Some(control.time_constant),
            _ => None,
        })
        .fold(0.0, f64::max);
    Stage {
        name: st.name.clone(),
        damping: st.damping,
        gravity: st.gravity,
        strains: modes
            .iter()
            .any(|m| matches!(m, WallMode::Velocity(v) if *v != 0.0)),
        modes,
        until: Until {
            max_time: u.max_time,
            stress_held: u
                .stress_held
                .as_ref()
                .map(|h| (h.tolerance, h.time_constants * tau)),
            axial_strain: u.axial_strain,
            failure: u.failure.as_ref().map(|f| FailureRule {
                drop: f.drop,
                strain_margin: f.strain_margin,
                plateau_strain: f.plateau_strain,
            }),
            wall_force: u.wall_force.as_ref().and_then(|wf| {
                let w = scene.walls.iter().position(|w| w.name == wf.wall)?;
                Some((w, wf.force, wf.hold))
            }),
        },
    }
}

/// Modes of the periodic cell's three axes in stage `st` (none without a cell): the
/// displacement of an axis is its shortening, its servo holds σ_kk on the current face.
fn cell_axis_modes(scene: &Scene, st: &StageSpec) -> Vec<WallMode> {
    let Some(cell) = PeriodicBox::of_scene(scene) else {
        return Vec::new();
    };
    (0..3)
        .map(|k| {
            let length = cell.length0[k];
            match st.cell.get(crate::scene::cell::AXES[k]) {
                None | Some(WallModeSpec::Fixed) => WallMode::Fixed,
                Some(WallModeSpec::Velocity(v)) => WallMode::Velocity(*v),
                Some(WallModeSpec::StrainRate(r)) => WallMode::Velocity(r * length),
                Some(WallModeSpec::InertialNumber(i)) => {
                    WallMode::Velocity(strain_rate_of_inertial_number(scene, st, *i) * length)
                }
                Some(WallModeSpec::Servo(s)) => {
                    let mut normal = [0.0; 3];
                    normal[k] = -1.0;
                    let face = WallSpec {
                        name: crate::scene::cell::AXES[k].to_string(),
                        point: cell.min,
                        normal,
                        friction: 0.0,
                        velocity: None,
                        displacement: None,
                        servo: None,
                    };
                    let area = cell.length0[(k + 1) % 3] * cell.length0[(k + 2) % 3];
                    let spec = ServoSpec {
                        area: Some(area),
                        ..s.clone()
                    };
                    WallMode::Servo {
                        control: servo_control(scene, &face, &spec),
                        lattice_area: true,
                    }
                }
            }
        })
        .collect()
}

/// ε̇ = I / (d √(ρ/p)) for the stage's inertial number I (see `WallModeSpec`).
pub fn strain_rate_of_inertial_number(scene: &Scene, st: &StageSpec, inertial: f64) -> f64 {
    let packing = cell_packing(scene);
    let radius = packing.map_or(f64::NAN, |p| p.sphere.radius);
    let density = packing
        .and_then(|p| scene.materials.get(&p.material))
        .map_or(f64::NAN, |m| m.density);
    let pressure = (st.walls.values().chain(st.cell.values()))
        .filter_map(|m| match m {
            WallModeSpec::Servo(s) => Some(s.stress),
            _ => None,
        })
        .fold(0.0, f64::max);
    inertial / (2.0 * radius * (density / pressure).sqrt())
}

/// Distance at t = 0 from wall `w` to the wall facing it on its axis (m).
fn opposite_distance(walls: &[([f64; 3], [f64; 3])], w: usize) -> f64 {
    let (p, n) = walls[w];
    walls
        .iter()
        .filter(|(_, m)| (0..3).all(|k| m[k] == -n[k]))
        .map(|(q, _)| (0..3).map(|k| (q[k] - p[k]) * n[k]).sum::<f64>())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;

    /// One closed FCC cell (R = 1 mm, a = 2√2 mm) in a box of six walls touching it.
    fn cell_scene(stages: &str) -> Scene {
        parse_scene("cell.toml", &cell_text(stages), &[])
            .expect("scene parses")
            .scene
    }

    /// The text of [`cell_scene`].
    fn cell_text(stages: &str) -> String {
        let r = 1.0e-3;
        let a = 2.0 * std::f64::consts::SQRT_2 * r;
        let (lo, hi) = (-r, a + r);
        let mut text = format!(
            r#"
[simulation]
duration = 1.0
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
[[packings]]
name = "cell"
lattice = "fcc"
cells = [1, 1, 1]
faces = "closed"
material = "glass"
sphere = {{ radius = {r:e}, seeding = 5e-4 }}
"#
        );
        for (name, k, sign, p) in [
            ("x_min", 0, 1.0, lo),
            ("x_max", 0, -1.0, hi),
            ("y_min", 1, 1.0, lo),
            ("y_max", 1, -1.0, hi),
            ("bottom", 2, 1.0, lo),
            ("top", 2, -1.0, hi),
        ] {
            let mut point = [0.0; 3];
            let mut normal = [0.0; 3];
            point[k] = p;
            normal[k] = sign;
            text +=
                &format!("[[walls]]\nname = \"{name}\"\npoint = {point:?}\nnormal = {normal:?}\n");
        }
        text += stages;
        text
    }

    const SERVO: &str = r#"{ servo = { stress = 5.0e4, area_of = "cell" } }"#;

    /// Advances the plan with wall forces from `forces(step, measure)` until it finishes
    /// or `steps` pass; returns the progress.
    fn drive(
        plan: &StagePlan,
        dt: f64,
        steps: usize,
        forces: impl Fn(usize, Option<&CellMeasure>) -> Vec<f64>,
    ) -> StageProgress {
        let mut p = plan.start();
        let mut kin: Vec<Option<ServoState>> = vec![Some(ServoState::default()); 6];
        for n in 0..steps {
            p.wall_displacements = (kin.iter().zip(&plan.walls))
                .map(|(k, (_, normal))| normal.map(|c| c * k.unwrap().displacement))
                .collect();
            let m = plan.measure(&p.wall_displacements, &p.wall_forces);
            let f = forces(n, m.as_ref());
            plan.advance(&mut p, kin.iter_mut(), &f, (n + 1) as f64 * dt, dt);
            if p.finished {
                break;
            }
        }
        p
    }

    #[test]
    fn a_strain_rate_wall_ends_its_stage_at_the_axial_strain() {
        let scene = cell_scene(
            r#"
[[stages]]
name = "shear"
walls = { top = { strain_rate = 10.0 } }
until = { axial_strain = 0.01, max_time = 1.0 }
"#,
        );
        let plan = StagePlan::build(&scene).expect("staged");
        assert_eq!(plan.axial, 2);
        let dt = 1e-6;
        let p = drive(&plan, dt, 10_000, |_, _| vec![0.0; 6]);
        assert!(p.finished);
        let r = &p.done[0];
        assert_eq!(r.reason, StageEnd::AxialStrain);
        // ε = r t: 0.01 at t = 1 ms (the first step moves nothing: the speed is set after it)
        assert!((r.end - 1.0e-3).abs() <= 2.0 * dt, "ended at {}", r.end);
    }

    /// A first stage moving the top wall until `wall_force` (the TOML value), then a short
    /// hold; `wall` carries 1 N at the steps where `loaded(step)`, every other wall none.
    /// Returns the plan and the progress after 20 000 steps of 0.1 µs.
    fn wall_force_run(
        wall_force: &str,
        wall: &str,
        loaded: impl Fn(usize) -> bool,
    ) -> (StagePlan, StageProgress) {
        let scene = cell_scene(&format!(
            "[[stages]]\nname = \"pack\"\nwalls = {{ top = {{ velocity = 0.5 }} }}\n\
             until = {{ wall_force = {wall_force}, max_time = 1.0 }}\n\n\
             [[stages]]\nname = \"hold\"\nuntil = {{ max_time = 1.0e-4 }}\n"
        ));
        let plan = StagePlan::build(&scene).expect("staged");
        let w = scene.walls.iter().position(|x| x.name == wall).unwrap();
        let p = drive(&plan, 1e-7, 20_000, |n, _| {
            let mut f = vec![0.0; 6];
            f[w] = if loaded(n) { 1.0 } else { 0.0 };
            f
        });
        (plan, p)
    }

    #[test]
    fn a_wall_force_ends_the_stage_once_the_filtered_force_reaches_it() {
        let dt = 1e-7;
        // the bottom wall is loaded from step 1000 on, with 1 N
        let (plan, p) = wall_force_run(r#"{ wall = "bottom", force = 0.2 }"#, "bottom", |n| {
            n >= 1000
        });
        let r = &p.done[0];
        assert_eq!(r.reason, StageEnd::WallForce);
        // after the filter's delay, well before the time limit
        assert!(
            r.end > 1000.0 * dt && r.end < 1000.0 * dt + 5.0 * plan.filter_time + 10.0 * dt,
            "{}",
            r.end
        );
        assert_eq!(p.done.len(), 2);
        // an unknown wall is an input error naming the field
        let bad = parse_scene(
            "cell.toml",
            &cell_text(
                "[[stages]]\nname = \"p\"\nuntil = { wall_force = { wall = \"floor\", force = 1.0 }, max_time = 1.0 }\n",
            ),
            &[],
        )
        .unwrap_err();
        assert!(
            bad.to_string().contains("stages[0].until.wall_force.wall"),
            "{bad}"
        );
    }

    #[test]
    fn a_wall_force_with_hold_ignores_a_spike_and_ends_once_the_force_stays() {
        let dt = 1e-7;
        // an impact: 1 N for 100 steps (10 µs < hold) at step 1000; then 1 N from step 5000
        let (plan, p) = wall_force_run(
            r#"{ wall = "top", force = 0.2, hold = 5.0e-5 }"#,
            "top",
            |n| (1000..1100).contains(&n) || n >= 5000,
        );
        let r = &p.done[0];
        assert_eq!(r.reason, StageEnd::WallForce);
        let held_from = 5000.0 * dt + plan.filter_time;
        assert!(
            r.end >= 5000.0 * dt + 5.0e-5
                && r.end < held_from + 5.0e-5 + 5.0 * plan.filter_time + 10.0 * dt,
            "{}",
            r.end
        );
    }

    #[test]
    fn the_stress_ratio_is_undefined_while_the_lateral_walls_only_graze() {
        let scene = cell_scene(&format!(
            r#"
[[stages]]
name = "shear"
walls = {{ top = {{ strain_rate = 10.0 }}, x_min = {SERVO}, x_max = {SERVO}, y_min = {SERVO}, y_max = {SERVO} }}
until = {{ max_time = 1.0 }}
"#
        ));
        let plan = StagePlan::build(&scene).expect("staged");
        let u = vec![[0.0; 3]; 6];
        let ratio = |lateral: f64| {
            plan.measure(&u, &[lateral, lateral, lateral, lateral, 1.0, 1.0])
                .expect("cell")
                .ratio
        };
        // equal areas at the start: σ1/σ3 is the force ratio
        assert!((ratio(0.25) - 4.0).abs() < 1e-12);
        assert!(
            (ratio(2.0 * RATIO_LATERAL_FLOOR) - 0.5 / RATIO_LATERAL_FLOOR).abs()
                < 1e-6 / RATIO_LATERAL_FLOOR
        );
        assert_eq!(ratio(1e-9), 0.0);
        assert_eq!(ratio(0.0), 0.0);
    }

    /// One shearing stage: the top wall at a strain rate, the lateral walls servo-held,
    /// ended by a 5 % drop below the peak and 2e-3 more strain.
    fn failure_stage_plan() -> StagePlan {
        let scene = cell_scene(&format!(
            r#"
[[stages]]
name = "shear"
walls = {{ top = {{ strain_rate = 10.0 }}, x_min = {SERVO}, x_max = {SERVO}, y_min = {SERVO}, y_max = {SERVO} }}
until = {{ failure = {{ drop = 0.05, strain_margin = 0.002 }}, max_time = 1.0 }}
"#
        ));
        StagePlan::build(&scene).expect("staged")
    }

    #[test]
    fn failure_is_detected_after_the_peak_and_the_stage_runs_on_for_the_margin() {
        let plan = failure_stage_plan();
        // σ_axial/σ_lateral (forces on equal areas at the start) rises to 3 at ε = 0.004
        // then falls linearly; the lateral walls carry 1 N
        let curve = |eps: f64| {
            if eps < 0.004 {
                1.0 + 500.0 * eps
            } else {
                3.0 - 200.0 * (eps - 0.004)
            }
        };
        let p = drive(&plan, 1e-6, 100_000, |_, m| {
            let eps = m.map_or(0.0, |m| m.strain[2]);
            let area = |k: usize| {
                m.map_or(1.0, |m| {
                    let l = m.distance.map(|d| d - 2.0e-3);
                    l[(k + 1) % 3] * l[(k + 2) % 3]
                })
            };
            // lateral stress 1 Pa·(1/area) normalised: forces ∝ area so σ_lat = const
            let lat = |k: usize| area(k) / area(0);
            let ax = curve(eps) * area(2) / area(0);
            vec![lat(0), lat(0), lat(1), lat(1), ax, ax]
        });
        let r = &p.done[0];
        assert_eq!(r.reason, StageEnd::Failure);
        let peak = r.peak.expect("peak");
        // the measured forces are low-pass filtered: the curve is seen late by
        // rate × τ_f of strain, and its corner rounded by as much
        let lag = 10.0 * plan.filter_time;
        assert!(lag > 0.0 && lag < 1e-4, "filter lag {lag} in strain");
        assert!(
            (peak.ratio - 3.0).abs() < 500.0 * lag,
            "peak {}",
            peak.ratio
        );
        assert!((peak.axial_strain - 0.004).abs() < 2e-5 + 2.0 * lag);
        let fail = r.failure.expect("failure");
        // 5 % below the peak: 2.85 at ε = 0.004 + 0.15/200
        assert!(
            (fail.axial_strain - 0.00475).abs() < 2e-5 + 2.0 * lag,
            "{fail:?}"
        );
        // the ratio falls linearly over the margin, 2.85 → 2.45: its mean is 2.65
        let residual = r.residual.expect("a post-failure mean");
        assert!(
            (residual - 2.65).abs() < 200.0 * (2.0 * lag + 2e-5),
            "residual {residual}"
        );
        // the strain measured at the end lags r·t by the step before the wall starts
        let end_strain = 10.0 * r.end;
        assert!(
            (end_strain - (fail.axial_strain + 0.002)).abs() < 5e-5,
            "ended at ε = {end_strain}, failure at {}",
            fail.axial_strain
        );
    }

    #[test]
    fn stress_held_ends_the_stage_after_the_hold_time_and_the_next_stage_starts() {
        let scene = cell_scene(&format!(
            r#"
[[stages]]
name = "hold"
walls = {{ top = {SERVO} }}
until = {{ stress_held = {{ tolerance = 0.01, time_constants = 1.0 }}, max_time = 1.0 }}
[[stages]]
name = "rest"
until = {{ max_time = 1.0e-4 }}
"#
        ));
        let plan = StagePlan::build(&scene).expect("staged");
        let (control, tau) = match &plan.stages[0].modes[5] {
            WallMode::Servo { control, .. } => (control.clone(), control.time_constant),
            m => panic!("top is {m:?}"),
        };
        let dt = tau / 1000.0;
        // the top wall pressing a spring of the servo's design stiffness: F = k s
        let mut p = plan.start();
        let mut kin: Vec<Option<ServoState>> = vec![Some(ServoState::default()); 6];
        let mut n = 0;
        let (mut settling, mut holding) = (0, 0);
        while p.index == 0 && n < 100_000 {
            // the progress line says whether the servo holds yet, and for how long
            match plan.waiting_on(&p, n as f64 * dt).as_deref() {
                Some("servos not yet within 1 %") => settling += 1,
                Some(s) if s.starts_with("servos within 1 % for ") => holding += 1,
                other => panic!("step {n}: {other:?}"),
            }
            let s = kin[5].unwrap().displacement;
            let mut f = vec![0.0; 6];
            f[5] = control.stiffness * s;
            p.wall_displacements = vec![[0.0; 3]; 6];
            plan.advance(&mut p, kin.iter_mut(), &f, (n + 1) as f64 * dt, dt);
            n += 1;
        }
        let r = &p.done[0];
        assert_eq!(r.reason, StageEnd::StressHeld);
        // the loop settles within 1 % in a few τ, then holds for one τ
        assert!(
            r.end > tau && r.end < 10.0 * tau,
            "ended at {} (τ = {tau})",
            r.end
        );
        assert_eq!(p.index, 1);
        assert!((p.started_at - r.end).abs() < 1e-15);
        assert!(settling > 0 && holding > 0, "{settling} {holding}");
        // the last stage ends on its time cap only: the ETA needs no condition
        assert_eq!(plan.waiting_on(&p, r.end), None);
    }

    #[test]
    fn the_progress_line_of_a_failure_stage_gives_the_ratio_the_peak_and_the_margin() {
        let plan = failure_stage_plan();
        let mut p = plan.start();
        // equal areas at the start: σ1/σ3 is the force ratio
        p.wall_displacements = vec![[0.0; 3]; 6];
        p.wall_forces = vec![1.0, 1.0, 1.0, 1.0, 2.5, 2.5];
        let said = |p: &StageProgress| plan.waiting_on(p, 0.0).expect("a condition");
        assert_eq!(said(&p), "σ1/σ3 2.500");
        let point = |ratio, axial_strain| RatioPoint {
            ratio,
            time: 0.0,
            axial_strain,
        };
        p.peak = Some(point(3.0, 4e-3));
        assert_eq!(said(&p), "σ1/σ3 2.500, peak 3.000 at axial strain 4.00e-3");
        // failure detected 1e-3 of strain ago: half the 2e-3 margin is run
        p.failure = Some(point(2.85, -1e-3));
        assert_eq!(said(&p), "failed at axial strain -1.00e-3, margin 50 % run");
    }
}
