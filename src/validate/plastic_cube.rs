//! `plastic_cube`: uniaxial stress loading, unloading and reverse loading of a J2 cube
//! against the exact linear-hardening curve (docs/THEORY.md §5).
//!
//! Measures: the law's own — the strain ε̃ = E − ½E² along the load axis and its
//! work-conjugate stress T̃ (see `crate::material::j2`). The cube [0, L]³ sits on rollers
//! (x = 0, y = 0, z = 0 held in their normal direction; lateral faces free), so the state is
//! homogeneous uniaxial stress for any mesh. The top face is driven along z. From its
//! displacement u and reaction F: λ = 1 + u/L, E₃₃ = (λ² − 1)/2, ε̃₃₃ = E₃₃ − E₃₃²/2 and
//! T̃₃₃ = (F/L²) / (λ (1 − E₃₃)) (P₃₃ = λ S₃₃, S₃₃ = (1 − E₃₃) T̃₃₃ for a diagonal state).
//!
//! Reference: the 1-D J2 model with the scene's E, σy and H, stepped along the measured
//! ε̃₃₃ (its return mapping is exact for linear hardening on monotone segments, at any
//! step). Error metric: max |T̃₃₃ − T̃_exact| over the path / max |T̃_exact|; target 1e-6.
//!
//! Drive: 0 → yield → +4εy → reverse yield → −4εy → yield → +4εy (εy = σy/E of the scene
//! as run), each leg a sin² velocity pulse that starts and ends at rest. The legs end at
//! the kinks of the exact curve, so the lateral contraction rate never jumps (it changes
//! at yield) and the cube does not ring; the inertia of a leg of duration T is a relative
//! (L/c_p)²/T² effect.

use super::record::{recorded_mesh, CaseOutput, Recorder};
use super::runner::{
    drive_file_name, drive_scene_header, load_case_scene, Case, CaseOutcome, Probe,
};
use super::scenes::Params;
use crate::error::{MufeError, Result};
use crate::io::plot::{Plot, Scale, Series};
use crate::scene::{parse_scene, ShapeSpec};
use crate::solver::build_solver;
use serde_json::json;

pub const SCENE: &str = include_str!("../../jobs/validation/plastic_cube.toml");

/// Accuracy target (fraction of the largest |T̃| of the path).
pub const TARGET: f64 = 1e-6;
/// Peak strain of the cycle in units of the yield strain σy/E.
pub const AMPLITUDE: f64 = 4.0;
/// Duration of each leg of the drive in wave transits L/c_p.
pub const LEG_TRANSITS: f64 = 8000.0;
/// Velocity samples per leg (the scene's histories are piecewise linear).
const LEG_SAMPLES: usize = 64;

/// The exact uniaxial J2 response with linear isotropic hardening.
#[derive(Debug, Clone, Copy)]
pub struct UniaxialJ2 {
    /// Young's modulus E (Pa).
    pub young: f64,
    /// σy (Pa).
    pub yield_stress: f64,
    /// H (Pa).
    pub hardening: f64,
}

/// State of the 1-D model: plastic strain, equivalent plastic strain, stress, plastic work
/// density.
#[derive(Debug, Clone, Copy, Default)]
pub struct Uniaxial {
    pub plastic: f64,
    pub equivalent: f64,
    pub stress: f64,
    pub plastic_work: f64,
}

impl UniaxialJ2 {
    /// Advances the 1-D state to total strain `strain`: trial σ = E(ε − εp); beyond the flow
    /// stress σy + Hα, Δα = (|σ| − σf)/(E + H). Exact for a monotone change of ε.
    pub fn advance(&self, s: &mut Uniaxial, strain: f64) {
        let trial = self.young * (strain - s.plastic);
        let flow = self.yield_stress + self.hardening * s.equivalent;
        if trial.abs() <= flow {
            s.stress = trial;
            return;
        }
        let d_alpha = (trial.abs() - flow) / (self.young + self.hardening);
        s.plastic += trial.signum() * d_alpha;
        s.equivalent += d_alpha;
        s.stress = trial - trial.signum() * self.young * d_alpha;
        // ∫ σf dα with σf linear in α: exact by the trapezoidal rule
        s.plastic_work +=
            0.5 * (flow + self.yield_stress + self.hardening * s.equivalent) * d_alpha;
    }

    /// The strains at which the drive's legs end: first yield, +A εy, reverse yield, −A εy,
    /// yield again, +A εy.
    pub fn leg_ends(&self, amplitude: f64) -> Vec<f64> {
        let ey = self.yield_stress / self.young;
        let peak = amplitude * ey;
        let mut s = Uniaxial::default();
        self.advance(&mut s, peak);
        let first_reversal = peak - 2.0 * s.stress.abs() / self.young;
        self.advance(&mut s, -peak);
        let second_reversal = -peak + 2.0 * s.stress.abs() / self.young;
        vec![ey, peak, first_reversal, -peak, second_reversal, peak]
    }
}

/// Top displacement u (m) of a cube of edge `l` at axial ε̃: E = 1 − √(1 − 2ε̃),
/// λ = √(1 + 2E).
fn displacement_at(strain: f64, l: f64) -> f64 {
    let green = 1.0 - (1.0 - 2.0 * strain).sqrt();
    ((1.0 + 2.0 * green).sqrt() - 1.0) * l
}

/// (ε̃₃₃, T̃₃₃) from the top displacement u and reaction force F of a cube of edge `l`.
fn measures(u: f64, force: f64, l: f64) -> (f64, f64) {
    let stretch = 1.0 + u / l;
    let green = 0.5 * (stretch * stretch - 1.0);
    (
        green - 0.5 * green * green,
        force / (l * l) / (stretch * (1.0 - green)),
    )
}

pub struct PlasticCubeCase;

struct Setup {
    law: UniaxialJ2,
    poisson_ratio: f64,
    density: f64,
    edge: f64,
}

impl PlasticCubeCase {
    fn setup(scene: &crate::scene::Scene) -> Result<Setup> {
        let g = scene
            .grains
            .first()
            .ok_or_else(|| MufeError::Run("plastic_cube: the scene has no grain".into()))?;
        let m = &scene.materials[&g.material];
        let ShapeSpec::Block(b) = &g.shape else {
            return Err(MufeError::Run(
                "plastic_cube: grain 0 must be a block".into(),
            ));
        };
        let Some(yield_stress) = m.yield_stress else {
            return Err(MufeError::Run(format!(
                "plastic_cube: material '{}' has no yield_stress",
                g.material
            )));
        };
        Ok(Setup {
            law: UniaxialJ2 {
                young: m.youngs_modulus,
                yield_stress,
                hardening: m.hardening_modulus.unwrap_or(0.0),
            },
            poisson_ratio: m.poisson_ratio,
            density: m.density,
            edge: b.size[0],
        })
    }

    /// The full scene of one run: the material and cube as run, rollers, the drive.
    fn scene_text(s: &Setup, divisions: usize) -> (String, f64) {
        let law = &s.law;
        let (lambda, mu) = crate::material::ElasticParameters {
            youngs_modulus: law.young,
            poisson_ratio: s.poisson_ratio,
            density: s.density,
        }
        .lame();
        let transit = s.edge / ((lambda + 2.0 * mu) / s.density).sqrt();
        let leg = LEG_TRANSITS * transit;
        let (mut times, mut values) = (vec![0.0], vec![0.0]);
        let mut strain = 0.0;
        for (k, end) in law.leg_ends(AMPLITUDE).into_iter().enumerate() {
            let du = displacement_at(end, s.edge) - displacement_at(strain, s.edge);
            // sin² pulse sampled at LEG_SAMPLES intervals: its trapezoidal integral is
            // v_max·T/2 exactly, so the leg ends at `end`
            let v_max = 2.0 * du / leg;
            for i in 1..=LEG_SAMPLES {
                let phase = i as f64 / LEG_SAMPLES as f64;
                times.push((k as f64 + phase) * leg);
                values.push(v_max * (std::f64::consts::PI * phase).sin().powi(2));
            }
            strain = end;
        }
        let duration = *times.last().unwrap_or(&0.0);
        let fmt_list = |v: &[f64], vector: bool| {
            v.iter()
                .map(|x| {
                    if vector {
                        format!("[0.0, 0.0, {x:.15e}]")
                    } else {
                        format!("{x:.15e}")
                    }
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        let l = s.edge;
        let tol = 1e-3 * l;
        let roller = |name: &str, point: [f64; 3], normal: [f64; 3], axis: usize| {
            let mut c = [false; 3];
            c[axis] = true;
            format!(
                "[[boundaries]]\nname = \"{name}\"\ngrain = \"cube\"\nselect = {{ beyond_plane = {{ point = [{:e}, {:e}, {:e}], normal = [{}, {}, {}] }} }}\ncomponents = [{}, {}, {}]\n",
                point[0], point[1], point[2], normal[0], normal[1], normal[2], c[0], c[1], c[2]
            )
        };
        let mut text = format!(
            "[simulation]\nduration = {duration:.15e}\n\n[materials.cube]\nyoungs_modulus = {:e}\npoisson_ratio = {}\ndensity = {:e}\nyield_stress = {:e}\nhardening_modulus = {:e}\n\n[[grains]]\nname = \"cube\"\nmaterial = \"cube\"\nshape = {{ block = {{ size = [{l:e}, {l:e}, {l:e}], divisions = [{divisions}, {divisions}, {divisions}] }} }}\n\n",
            law.young, s.poisson_ratio, s.density, law.yield_stress, law.hardening
        );
        text += &roller("x0", [tol, 0.0, 0.0], [-1.0, 0.0, 0.0], 0);
        text += &roller("y0", [0.0, tol, 0.0], [0.0, -1.0, 0.0], 1);
        text += &roller("z0", [0.0, 0.0, tol], [0.0, 0.0, -1.0], 2);
        text += &format!(
            "{}velocity = {{ times = [{}], values = [{}] }}\n",
            roller("top", [0.0, 0.0, l - tol], [0.0, 0.0, 1.0], 2),
            fmt_list(&times, false),
            fmt_list(&values, true)
        );
        (text, duration)
    }
}

impl Case for PlasticCubeCase {
    fn name(&self) -> &'static str {
        "plastic_cube"
    }

    fn shipped_scene(&self) -> &'static str {
        SCENE
    }

    /// The run scene at the default meshing ratio (the mesh does not change the answer).
    fn generated_scene(&self, overrides: &[String], _params: &Params) -> Result<String> {
        let base = load_case_scene("plastic_cube", SCENE, overrides)?;
        let setup = Self::setup(&base.scene)?;
        Ok(
            drive_scene_header("plastic_cube", "the material and the cube", 0.5)
                + &Self::scene_text(&setup, 2).0,
        )
    }

    /// jobs/validation/plastic_cube.toml is the input the run scene is built from.
    fn generated_file_name(&self) -> String {
        drive_file_name("plastic_cube")
    }

    /// MR = cell edge / cube edge.
    fn sweep_mrs(&self) -> Vec<f64> {
        vec![0.5, 0.25]
    }

    fn quick_mr(&self) -> f64 {
        0.5
    }

    fn full_target(&self) -> f64 {
        TARGET
    }

    fn run(
        &self,
        mr: f64,
        quick: bool,
        overrides: &[String],
        _params: &Params,
        record: Option<&Recorder>,
    ) -> Result<CaseOutcome> {
        let base = load_case_scene("plastic_cube", SCENE, overrides)?;
        let setup = Self::setup(&base.scene)?;
        let divisions = (1.0 / mr).round().max(1.0) as usize;
        let (text, duration) = Self::scene_text(&setup, divisions);
        let loaded = parse_scene("<plastic_cube drive>", &text, &[])?;
        let mut solver = build_solver(&loaded)?;
        let mesh = recorded_mesh(record, &loaded)?;
        let mut output =
            CaseOutput::open(record, self.name(), mr, &loaded, mesh.as_ref(), &solver)?;
        let mut probe = Probe::new(&solver);
        let steps = (duration / solver.model.dt).ceil() as u64;
        let law = setup.law;
        let mut exact = Uniaxial::default();
        let (mut err, mut scale): (f64, f64) = (0.0, 0.0);
        let mut curve = Vec::new();
        let mut error_curve = Vec::new();
        let plot_every = (steps / 2000).max(1);
        while solver.state.step < steps {
            solver.step()?;
            output.after_step(&solver, solver.state.step == steps)?;
            probe.sample(&solver);
            let (strain, stress) = measures(
                probe.get("top_displacement_z")?,
                probe.get("top_force_z")?,
                setup.edge,
            );
            law.advance(&mut exact, strain);
            err = err.max((stress - exact.stress).abs());
            scale = scale.max(exact.stress.abs());
            if solver.state.step % plot_every == 0 {
                curve.push((1e3 * strain, 1e-6 * stress));
                error_curve.push((1e3 * strain, stress - exact.stress));
            }
        }
        let error = err / scale.max(f64::MIN_POSITIVE);
        for p in &mut error_curve {
            p.1 *= 100.0 / scale.max(f64::MIN_POSITIVE);
        }
        let volume = setup.edge.powi(3);
        let e = &solver.state.energy;
        let mut details = serde_json::Map::new();
        details.insert("plastic_dissipation_J".into(), json!(e.plastic_dissipation));
        details.insert(
            "exact_plastic_work_J".into(),
            json!(volume * exact.plastic_work),
        );
        details.insert("peak_stress_Pa".into(), json!(scale));
        output.finish(&solver, &mut details)?;
        Ok(CaseOutcome {
            case: self.name().into(),
            mr,
            elements: solver.model.num_elements(),
            steps: solver.state.step,
            wall_s: 0.0,
            error,
            target: self.target(quick),
            pass: error <= self.target(quick),
            details,
            curve,
            error_curve,
        })
    }

    fn error_axis(&self) -> (&'static str, Scale) {
        ("axial strain ε̃₃₃ (‰)", Scale::Linear)
    }

    fn plot(&self, _outcomes: &[CaseOutcome]) -> (Plot<'static>, Vec<Series>) {
        let theory = load_case_scene("plastic_cube", SCENE, &[])
            .ok()
            .and_then(|b| Self::setup(&b.scene).ok())
            .map(|s| {
                let mut state = Uniaxial::default();
                let mut points = Vec::new();
                let mut from = 0.0;
                for end in s.law.leg_ends(AMPLITUDE) {
                    for i in 0..=200 {
                        let strain = from + (end - from) * i as f64 / 200.0;
                        s.law.advance(&mut state, strain);
                        points.push((1e3 * strain, 1e-6 * state.stress));
                    }
                    from = end;
                }
                Series {
                    label: "exact J2, linear hardening (THEORY §5)".into(),
                    points,
                    theory: true,
                }
            });
        (
            Plot {
                title: "plastic_cube: uniaxial stress cycle",
                x_label: "axial strain ε̃₃₃ (‰)",
                y_label: "axial stress T̃₃₃ (MPa)",
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series: vec![],
            },
            theory.into_iter().collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measures_invert_the_displacement_map() {
        for strain in [-0.01, -1e-4, 0.0, 3e-3, 0.02] {
            let u = displacement_at(strain, 2e-3);
            assert!((measures(u, 0.0, 2e-3).0 - strain).abs() < 1e-15);
        }
    }

    #[test]
    fn exact_curve_has_the_textbook_slopes_and_reversal() {
        let law = UniaxialJ2 {
            young: 2e11,
            yield_stress: 2e8,
            hardening: 2e10,
        };
        let ey = 1e-3;
        let mut s = Uniaxial::default();
        law.advance(&mut s, 0.5 * ey);
        assert!((s.stress - 1e8).abs() < 1e-3);
        law.advance(&mut s, 3.0 * ey);
        // tangent E H/(E + H) beyond yield
        let tangent = 2e11 * 2e10 / 2.2e11;
        assert!((s.stress - (2e8 + tangent * 2.0 * ey)).abs() < 1e-3 * 2e8);
        let ends = law.leg_ends(3.0);
        // elastic unloading spans twice the flow stress
        assert!((ends[1] - ends[2] - 2.0 * s.stress / 2e11).abs() < 1e-15);
    }
}
