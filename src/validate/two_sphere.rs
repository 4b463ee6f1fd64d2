//! Two identical spheres touching at the origin: the lower one is held fixed beyond a
//! plane below the contact (boundary `base`), the upper one is moved rigidly beyond a plane
//! above it (boundary `drive`) — first down to the normal force N, then tangentially
//! (Mindlin), twisted about the normal (torsion) or rotated about its own centre (rolling).
//! The planes are at ∓R/2 from the contact in the shipped scenes (`clamp` of
//! [`super::scenes::TwoSphereParams`]; docs/BENCHMARKS.md shows the far hemispheres too).
//! The scene run is generated from the material, radius and friction of the case scene
//! (after `--set`), so the loads, drives and meshes follow them ([`super::scenes`]).
//!
//! What is measured: the force and moment the contact transmits to the lower sphere, i.e.
//! the base reaction plus the rate of change of the lower sphere's linear and angular
//! momentum (so the vibration of its free part does not show), and N from the same
//! balance. The reference is evaluated with the N measured during the case motion, so a
//! mesh whose normal stiffness differs a little from Hertz is still judged on the
//! tangential law alone.
//!
//! Error metrics (fractions of the limit value):
//! - mindlin: max |Q − Q_MD(δt)| / μN over the first loading branch (the first unloading
//!   branch against the Masing rule is reported beside it);
//! - torsion: max |M − M_Lubkin(2β)| / M_max over the loading branch (exact parametric curve);
//! - rolling: max |M − M_ref(θ)| / (μN R') over the loading branch, R' = R − δn/2 the
//!   lever of the contact force about the upper centre.

use super::mindlin_cyclic::{analyse as analyse_cycle, CyclePoint, LOOP_TOLERANCE};
use super::record::{recorded_mesh, CaseOutput, Recorder};
use super::reference::{Lubkin, Mindlin, Rolling};
use super::runner::{
    case_inputs, case_solver, deformation_kinetic_energy, generated_case_scene, outcome_scene,
    scene_details, Case, CaseOutcome, Probe,
};
use super::scenes::{Params, SceneInputs};
use crate::error::Result;
use crate::io::plot::{Plot, Scale, Series};
use crate::material::ElasticParameters;
use serde_json::json;

/// Which tangential law a case checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    Mindlin,
    /// A full cycle 0 → +δa → −δa → +δa judged by [`super::mindlin_cyclic`].
    MindlinCyclic,
    Torsion,
    Rolling,
}

pub struct TwoSphereCase {
    pub kind: Kind,
}

/// One sample of a run: time, drive coordinate x, static response y (from the base
/// reaction), N, drive z displacement, and the lower sphere's linear momentum and angular
/// momentum about its centre.
struct Sample {
    t: f64,
    x: f64,
    y: f64,
    n: f64,
    dz: f64,
    p: [f64; 3],
    l: [f64; 3],
    /// ALLFD + ALLVD so far (J).
    dissipated: f64,
    tangential: bool,
}

/// Linear momentum and angular momentum about `centre` of one grain (with the masses the
/// dynamics use).
fn momentum(
    solver: &crate::solver::Solver,
    grain: usize,
    centre: [f64; 3],
) -> ([f64; 3], [f64; 3]) {
    let (model, state) = (&solver.model, &solver.state);
    let (mut p, mut l) = ([0.0; 3], [0.0; 3]);
    for n in model.grains[grain].nodes.clone() {
        let (m, x, v) = (model.mass[n], state.x[n], state.v[n]);
        let r = [x[0] - centre[0], x[1] - centre[1], x[2] - centre[2]];
        for i in 0..3 {
            p[i] += m * v[i];
        }
        l[0] += m * (r[1] * v[2] - r[2] * v[1]);
        l[1] += m * (r[2] * v[0] - r[0] * v[2]);
        l[2] += m * (r[0] * v[1] - r[1] * v[0]);
    }
    (p, l)
}

pub const MINDLIN_SCENE: &str = include_str!("../../jobs/validation/mindlin.toml");
pub const MINDLIN_CYCLIC_SCENE: &str = include_str!("../../jobs/validation/mindlin_cyclic.toml");
pub const TORSION_SCENE: &str = include_str!("../../jobs/validation/torsion.toml");
pub const ROLLING_SCENE: &str = include_str!("../../jobs/validation/rolling.toml");

struct Setup {
    material: ElasticParameters,
    radius: f64,
    mu: f64,
    /// Rolling: distance from the upper sphere's centre to the contact plane, R − δn/2
    /// (δn = approach of the centres), the lever of the tangential force and of δt = lever·θ.
    lever: f64,
}

impl TwoSphereCase {
    fn scene_text(&self) -> &'static str {
        match self.kind {
            Kind::Mindlin => MINDLIN_SCENE,
            Kind::MindlinCyclic => MINDLIN_CYCLIC_SCENE,
            Kind::Torsion => TORSION_SCENE,
            Kind::Rolling => ROLLING_SCENE,
        }
    }

    fn setup(inputs: &SceneInputs) -> Setup {
        Setup {
            material: inputs.material,
            radius: inputs.radius,
            mu: inputs.friction,
            lever: inputs.radius,
        }
    }

    /// (x, y, N) at the current sample: the drive's tangential displacement or angle, and
    /// the force or moment transmitted through the contact, read at the fixed base of the
    /// lower sphere. The base barely moves, so its reaction is the contact force without
    /// the inertia of the driven sphere (which the drive's own reaction includes whenever
    /// the drive accelerates). Signs follow the drive: positive motion, positive response.
    /// Also returns the drive's z displacement (the approach of the centres, negative).
    fn sample(&self, probe: &Probe, radius: f64) -> Result<(f64, f64, f64, f64)> {
        let n = probe.get("base_force_z")?;
        let dz = probe.get("drive_displacement_z")?;
        Ok(match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic => (
                probe.get("drive_displacement_x")?,
                -probe.get("base_force_x")?,
                n,
                dz,
            ),
            Kind::Torsion => (
                probe.get("drive_rotation_z")?,
                -probe.get("base_moment_z")?,
                n,
                dz,
            ),
            Kind::Rolling => {
                // moment about the upper sphere's current centre (0,0,R+dz) of the contact
                // force and couple, from the base reaction about the lower centre (0,0,−R)
                let m = probe.get("base_moment_x")?
                    + (2.0 * radius + dz) * probe.get("base_force_y")?;
                (probe.get("drive_rotation_x")?, -m, n, dz)
            }
        })
    }

    fn reference(&self, s: &Setup, n: f64, x: f64) -> f64 {
        match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic => {
                Mindlin::identical_spheres(&s.material, s.radius, s.mu, n).loading(x)
            }
            Kind::Torsion => Lubkin::identical_spheres(&s.material, s.radius, s.mu, n)
                .moment_at_relative_twist(x),
            Kind::Rolling => Rolling {
                radius: s.lever,
                mindlin: Mindlin::identical_spheres(&s.material, s.radius, s.mu, n),
            }
            .moment(x),
        }
    }

    fn limit(&self, s: &Setup, n: f64) -> f64 {
        match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic => s.mu * n,
            Kind::Torsion => {
                Lubkin::identical_spheres(&s.material, s.radius, s.mu, n).full_slip_moment()
            }
            Kind::Rolling => s.mu * n * s.lever,
        }
    }

    /// Axis labels of the dimensionless plots: x / x_scale(N), y / limit(N), so that every
    /// meshing ratio (each with its own measured N) is drawn against one theory curve.
    fn labels(&self) -> (&'static str, &'static str) {
        match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic => (
                "relative tangential displacement δt / δt,max",
                "tangential force Q / μN",
            ),
            Kind::Torsion => (
                "twist per sphere G a² β / (μN)",
                "twisting moment M / M_max (M_max = 3πμNa/16)",
            ),
            Kind::Rolling => (
                "rotation θ / θ_slip (θ_slip = δt,max / R')",
                "rolling moment M / (μN R'), R' = R − δn/2",
            ),
        }
    }

    /// The drive coordinate's natural scale at normal force n: δt,max (Mindlin), μN/(G a²)
    /// per sphere, i.e. 2μN/(G a²) of relative twist (torsion), δt,max / lever (rolling).
    fn x_scale(&self, s: &Setup, n: f64) -> f64 {
        let md = Mindlin::identical_spheres(&s.material, s.radius, s.mu, n);
        match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic => md.slip_displacement,
            Kind::Torsion => {
                let l = Lubkin::identical_spheres(&s.material, s.radius, s.mu, n);
                2.0 * l.mu * l.normal_force / (l.shear_modulus * l.a * l.a)
            }
            Kind::Rolling => md.slip_displacement / s.lever,
        }
    }
}

impl Case for TwoSphereCase {
    fn name(&self) -> &'static str {
        match self.kind {
            Kind::Mindlin => "mindlin",
            Kind::MindlinCyclic => "mindlin_cyclic",
            Kind::Torsion => "torsion",
            Kind::Rolling => "rolling",
        }
    }

    fn shipped_scene(&self) -> &'static str {
        self.scene_text()
    }

    fn sweep_mrs(&self) -> Vec<f64> {
        vec![0.036, 0.018, 0.009, 0.0045]
    }

    /// The coarsest meshing ratio that meets the full target (docs/BENCHMARKS.md).
    fn quick_mr(&self) -> f64 {
        match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic => 0.009,
            Kind::Torsion | Kind::Rolling => 0.018,
        }
    }

    fn full_target(&self) -> f64 {
        match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic => 0.05,
            Kind::Torsion => 0.08,
            Kind::Rolling => 0.10,
        }
    }

    fn run(
        &self,
        mr: f64,
        quick: bool,
        overrides: &[String],
        params: &Params,
        record: Option<&Recorder>,
    ) -> Result<CaseOutcome> {
        let name = self.name();
        let inputs = case_inputs(name, self.scene_text(), overrides)?;
        let setup = Self::setup(&inputs);
        let s = mr * 2.0 * setup.radius;
        let sets = vec![
            format!("grains[0].shape.sphere.refine[0].seeding={s:e}"),
            format!("grains[1].shape.sphere.refine[0].seeding={s:e}"),
        ];
        let (loaded, _) = generated_case_scene(name, self.scene_text(), overrides, params, &sets)?;
        let mut solver = case_solver(&loaded)?;
        let mesh = recorded_mesh(record, &loaded)?;
        let mut output = CaseOutput::open(record, name, mr, &loaded, mesh.as_ref(), &solver)?;
        let mut probe = Probe::new(&solver);
        let sample_every =
            ((loaded.scene.output.history_interval.unwrap_or(2e-8) / solver.model.dt).round()
                as u64)
                .max(1);
        let max_steps = (loaded.scene.simulation.duration / solver.model.dt).ceil() as u64;

        // the lower sphere's momentum: its rate is added to the base reaction so that the
        // measured force and moment are those of the contact, without the inertia of the
        // lower sphere's free half (whose bending vibration would show up otherwise)
        let lower = solver
            .model
            .grains
            .iter()
            .position(|g| g.name == "lower")
            .unwrap_or(0);
        // about the point the base moment refers to
        let centre_lower = loaded
            .scene
            .boundaries
            .iter()
            .find(|b| b.name == "base")
            .and_then(|b| b.centre)
            .unwrap_or(solver.model.grains[lower].centre0);
        let mut samples: Vec<Sample> = Vec::new();
        let (mut ke_ie, mut ke_def_ie): (f64, f64) = (0.0, 0.0);
        let mut tangential_started = false;
        while solver.state.step < max_steps {
            solver.step()?;
            output.after_step(&solver, solver.state.step == max_steps)?;
            if solver.state.step % sample_every != 0 {
                continue;
            }
            probe.sample(&solver);
            let (x, y, n, dz) = self.sample(&probe, setup.radius)?;
            let (p, l) = momentum(&solver, lower, centre_lower);
            // the second phase starts when the drive first moves in the case's direction
            if !tangential_started && x.abs() > 0.0 {
                tangential_started = true;
            }
            samples.push(Sample {
                t: solver.state.time,
                x,
                y,
                n,
                dz,
                p,
                l,
                dissipated: probe.get("friction_dissipation")?
                    + probe.get("damping_dissipation")?,
                tangential: tangential_started,
            });
            if tangential_started {
                let ie = probe.get("internal_energy")?.max(1e-300);
                ke_ie = ke_ie.max(probe.get("kinetic_energy")? / ie);
                ke_def_ie = ke_def_ie.max(deformation_kinetic_energy(&solver) / ie);
            }
        }
        let mut raw = Vec::new();
        let mut cycle = Vec::new();
        let mut inertia_max: f64 = 0.0;
        for k in 0..samples.len() {
            if !samples[k].tangential {
                continue;
            }
            let (a, b) = (
                &samples[k.saturating_sub(1)],
                &samples[(k + 1).min(samples.len() - 1)],
            );
            let dt = (b.t - a.t).max(1e-300);
            let dp: Vec<f64> = (0..3).map(|i| (b.p[i] - a.p[i]) / dt).collect();
            let dl: Vec<f64> = (0..3).map(|i| (b.l[i] - a.l[i]) / dt).collect();
            let smp = &samples[k];
            let correction = match self.kind {
                Kind::Mindlin | Kind::MindlinCyclic => dp[0],
                Kind::Torsion => dl[2],
                Kind::Rolling => dl[0] + (2.0 * setup.radius + smp.dz) * dp[1],
            };
            inertia_max = inertia_max.max(correction.abs());
            raw.push((smp.x, smp.y + correction, smp.n - dp[2], smp.dz));
            if self.kind == Kind::MindlinCyclic {
                cycle.push(CyclePoint {
                    x: smp.x,
                    q: smp.y + correction,
                    dissipated: smp.dissipated,
                });
            }
        }
        let (mut n_min, mut n_max) = (f64::INFINITY, f64::NEG_INFINITY);
        for r in &raw {
            n_min = n_min.min(r.2);
            n_max = n_max.max(r.2);
        }
        let mut curve = Vec::new();
        let n_mean = raw.iter().map(|r| r.2).sum::<f64>() / raw.len() as f64;
        let dz_mean = raw.iter().map(|r| r.3).sum::<f64>() / raw.len() as f64;
        let mut setup = setup;
        setup.lever = setup.radius + 0.5 * dz_mean;
        let limit = self.limit(&setup, n_mean);
        // loading branch: from the start until the first reversal of x
        // loading branch: up to the first reversal (|x| falls back from its running maximum)
        let mut x_peak_index = 0;
        for (i, r) in raw.iter().enumerate() {
            if r.0.abs() >= raw[x_peak_index].0.abs() {
                x_peak_index = i;
            } else if r.0.abs() < 0.99 * raw[x_peak_index].0.abs() {
                break;
            }
        }
        let x_scale = self.x_scale(&setup, n_mean);
        let mut err: f64 = 0.0;
        let mut error_curve = Vec::new();
        for &(x, y, _, _) in &raw[..=x_peak_index] {
            let y_ref = self.reference(&setup, n_mean, x);
            err = err.max((y - y_ref).abs() / limit);
            error_curve.push((x / x_scale, 100.0 * (y - y_ref) / limit));
        }
        curve.extend(raw.iter().map(|r| (r.0 / x_scale, r.1 / limit)));
        // Mindlin: the first unloading branch against the Masing rule from the FE's own
        // reversal point (a check of the hysteresis, beside the loading-branch metric)
        let masing_error =
            (self.kind == Kind::Mindlin && x_peak_index + 1 < raw.len()).then(|| {
                let md =
                    Mindlin::identical_spheres(&setup.material, setup.radius, setup.mu, n_mean);
                let (x_star, q_star) = (raw[x_peak_index].0, raw[x_peak_index].1);
                let mut x_min = x_star;
                let mut e: f64 = 0.0;
                for r in &raw[x_peak_index..] {
                    if r.0 > x_min + 0.01 * x_star.abs() {
                        break; // second reversal
                    }
                    x_min = x_min.min(r.0);
                    e = e.max((r.1 - md.unloading(x_star, q_star, r.0)).abs() / limit);
                }
                e
            });
        let target = self.target(quick);
        let mut details = serde_json::Map::new();
        let mut pass = err <= target;
        if self.kind == Kind::MindlinCyclic {
            let md = Mindlin::identical_spheres(&setup.material, setup.radius, setup.mu, n_mean);
            let cycle = analyse_cycle(&cycle, &md)?;
            err = cycle.error;
            error_curve = cycle.error_curve;
            pass = err <= target && cycle.loop_balance_error <= LOOP_TOLERANCE;
            details.extend(cycle.details);
        }
        details.insert("normal_force_mean_n".into(), json!(n_mean));
        if let Some(e) = masing_error {
            details.insert("masing_unloading_error".into(), json!(e));
        }
        details.insert("normal_force_range_n".into(), json!([n_min, n_max]));
        details.insert("limit_value".into(), json!(limit));
        details.insert("approach_of_centres_m".into(), json!(-dz_mean));
        details.insert("lever_arm_m".into(), json!(setup.lever));
        // largest correction of the base reaction by the lower sphere's momentum rate
        details.insert(
            "max_inertia_correction_over_limit".into(),
            json!(inertia_max / limit),
        );
        // ALLKE includes the driven sphere's rigid rotation; the vibration part is the
        // quasi-static measure
        details.insert("max_kinetic_over_internal".into(), json!(ke_ie));
        details.insert(
            "max_deformation_kinetic_over_internal".into(),
            json!(ke_def_ie),
        );
        details.insert("seeding_at_contact_m".into(), json!(s));
        details.insert("scene".into(), scene_details(&inputs));
        details.insert(
            "friction_dissipation_j".into(),
            json!(solver.state.energy.friction_dissipation),
        );
        output.finish(&solver, &mut details)?;
        Ok(CaseOutcome {
            case: name.into(),
            mr,
            elements: solver.model.num_elements(),
            steps: solver.state.step,
            wall_s: 0.0,
            error: err,
            target,
            pass,
            details,
            curve,
            error_curve,
        })
    }

    fn error_axis(&self) -> (&'static str, Scale) {
        (self.labels().0, Scale::Linear)
    }

    fn plot(&self, outcomes: &[CaseOutcome]) -> (Plot<'static>, Vec<Series>) {
        // dimensionless: one theory curve for all meshing ratios (each FE curve is scaled
        // with its own measured N)
        let x_max = outcomes
            .iter()
            .flat_map(|o| o.curve.iter().map(|p| p.0.abs()))
            .fold(0.0, f64::max)
            .max(1e-9);
        let xs = |from: f64, to: f64| (0..=200).map(move |i| from + (to - from) * i as f64 / 200.0);
        let unit = Mindlin {
            mu: 1.0,
            normal_force: 1.0,
            slip_displacement: 1.0,
        };
        let mut theory = Vec::new();
        match self.kind {
            Kind::Mindlin | Kind::MindlinCyclic | Kind::Rolling => {
                theory.push(Series {
                    label: "theory, loading (Mindlin)".into(),
                    points: xs(0.0, x_max).map(|x| (x, unit.loading(x))).collect(),
                    theory: true,
                });
                if self.kind != Kind::Rolling {
                    // Masing unloading from the reversal point and reloading from the other end
                    let (d, q) = (x_max, unit.loading(x_max));
                    theory.push(Series {
                        label: "Masing unloading / reloading".into(),
                        points: xs(d, -d).map(|x| (x, unit.unloading(d, q, x))).collect(),
                        theory: true,
                    });
                    theory.push(Series {
                        label: String::new(),
                        points: xs(-d, d).map(|x| (x, unit.unloading(-d, -q, x))).collect(),
                        theory: true,
                    });
                }
            }
            Kind::Torsion => {
                // Lubkin's curve is universal in these coordinates: evaluate it for any N
                let inputs = SceneInputs::paper();
                let (material, radius, mu) = outcomes.iter().find_map(outcome_scene).unwrap_or((
                    inputs.material,
                    inputs.radius,
                    inputs.friction,
                ));
                let s = Setup {
                    material,
                    radius,
                    mu,
                    lever: radius,
                };
                {
                    let l = Lubkin::identical_spheres(&s.material, s.radius, s.mu, 1.0);
                    let scale = self.x_scale(&s, 1.0);
                    let pts = xs(0.0, x_max)
                        .map(|x| {
                            (
                                x,
                                l.moment_at_relative_twist(x * scale) / l.full_slip_moment(),
                            )
                        })
                        .collect();
                    theory.push(Series {
                        label: "theory (Lubkin, exact)".into(),
                        points: pts,
                        theory: true,
                    });
                }
            }
        }
        let (xl, yl) = self.labels();
        let title = match self.kind {
            Kind::Mindlin => "Mindlin–Deresiewicz: tangential loading at constant N",
            Kind::MindlinCyclic => {
                "Mindlin–Deresiewicz–Masing: a full tangential cycle at constant N"
            }
            Kind::Torsion => "Torsion about the contact normal (Lubkin)",
            Kind::Rolling => "Rolling about a fixed centre",
        };
        (
            Plot {
                title,
                x_label: xl,
                y_label: yl,
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series: vec![],
            },
            theory,
        )
    }
}
