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
mod tests;
