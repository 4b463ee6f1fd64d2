//! Curved non-spherical contact: an ellipsoidal grain, imported from STL, squeezed
//! between two rigid frictionless plates along its shortest axis, against Hertz theory of
//! elliptical contact ([`EllipticHertz`], docs/THEORY.md §1b).
//!
//! The case scene gives the material and the ellipsoid (its STL, any semi-axes A, B ≥ C,
//! axis-aligned, centred on its origin); the tip radii R₁ = A²/C, R₂ = B²/C set the theory.
//! Each meshing ratio MR = s/(2R_e) (s = facet edge at the tips, R_e = √(R₁R₂)) writes a
//! new STL of the same ellipsoid with fine tips and runs it through the surface import,
//! so the grain is meshed exactly as a user's STL is.
//!
//! Error metric over the window of equivalent contact radius √(ab)/R_e in [`WINDOW`]
//! (of the theory force at the measured approach): the larger of
//! - max |F − F_H(δ)|/F_H(δ), plate force against elliptical Hertz at the approach δ of
//!   each plate, and
//! - max |(b/a)_FE − (b/a)_H|/(b/a)_H, the contact ellipse's axis ratio, measured from the
//!   second moments of the plates' nodal contact forces (a² = 5⟨x²⟩ for the Hertz
//!   pressure), averaged between samples.

use super::elliptic_hertz::EllipticHertz;
use super::record::{recorded_mesh, CaseOutput, Recorder};
use super::reference::{FiniteSphereTable, Hertz};
use super::runner::{case_solver, load_case_scene, Case, CaseOutcome, Probe};
use super::scenes::{HertzEllipsoidParams, Params, SceneInputs};
use crate::error::{num, InputError, MufeError, Result};
use crate::io::plot::{self, Plot, Scale, Series};
use crate::material::ElasticParameters;
use crate::mesh::ellipsoid::{fit_axis_aligned_ellipsoid, TipRefinedEllipsoid};
use crate::mesh::import::{formats, Prepared};
use crate::scene::{parse_scene, LoadedScene, ShapeSpec};
use serde_json::json;
use std::path::{Path, PathBuf};

pub const NAME: &str = "hertz_ellipsoid";
pub const SCENE: &str = include_str!("../../jobs/validation/hertz_ellipsoid.toml");
/// The case scene's ellipsoid (1.0 × 0.8 × 0.75 mm, fine tips at the quick MR).
pub const SHIPPED_STL: &[u8] = include_bytes!("../../jobs/validation/hertz_ellipsoid.stl");
const STL_NAME: &str = "hertz_ellipsoid.stl";

/// Window of the error metric, as √(ab)/R_e of the theory force: small enough that the
/// half-space theory holds to ~1 % for a body whose depth C is ~R_e (a sphere between
/// plates is +0.5 % stiffer than half-space Hertz at a/R = 0.017 and +1.2 % at 0.03, the
/// finite-body stiffening growing ∝ a/depth; the run reports this estimate at a/C), large
/// enough to hold ≥ 4 tip elements across the contact's minor axis at the finest MR.
pub const WINDOW: (f64, f64) = (0.01, 0.02);

/// Accuracy target at the finest meshing ratio (fraction).
pub const TARGET: f64 = 0.05;

/// Meshing ratio of the quick run and of the shipped STL.
pub const QUICK_MR: f64 = 0.0019;

/// Largest |x²/A² + y²/B² + z²/C² − 1| accepted for the case's STL (binary STL stores
/// f32 coordinates: ~1e-7 relative).
const ELLIPSOID_TOLERANCE: f64 = 1e-5;

/// What the case scene gives: material and ellipsoid.
struct Setup {
    inputs: SceneInputs,
    semi_axes: [f64; 3],
    theory: EllipticHertz,
}

impl Setup {
    fn equivalent_radius(&self) -> f64 {
        self.theory.equivalent_radius()
    }
}

/// The case scene after `overrides`: the shipped one is parsed next to a copy of its STL
/// in a temporary directory, so `mufe validate` runs from any working directory.
fn load_setup(overrides: &[String]) -> Result<Setup> {
    let loaded = if std::env::var_os("MUFE_VALIDATION_SCENES").is_some() {
        load_case_scene(NAME, SCENE, overrides)?
    } else {
        let dir = std::env::temp_dir().join(format!("mufe-{NAME}-{}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .and_then(|_| std::fs::write(dir.join(STL_NAME), SHIPPED_STL))
            .map_err(|e| MufeError::Io(format!("{}: {e}", dir.display())))?;
        let path = dir.join(format!("{NAME}.toml"));
        let loaded = parse_scene(&path.display().to_string(), SCENE, overrides);
        let setup = loaded.map_err(MufeError::from).and_then(|l| setup_from(&l));
        // the copy is read once, here
        let _ = std::fs::remove_dir_all(&dir);
        return setup;
    };
    setup_from(&loaded)
}

fn setup_from(loaded: &LoadedScene) -> Result<Setup> {
    let file = loaded.path.clone();
    let scene = &loaded.scene;
    let bad = |item: &str, m: String| MufeError::Input(InputError::new(&file, item, m));
    if scene.grains.len() != 1 {
        return Err(bad(
            "grains",
            format!(
                "the {NAME} case needs one ellipsoid grain, the scene has {}",
                scene.grains.len()
            ),
        ));
    }
    let g = &scene.grains[0];
    let ShapeSpec::Surface(spec) = &g.shape else {
        return Err(bad(
            "grains[0].shape",
            format!("the {NAME} case needs a surface shape (an ellipsoid STL)"),
        ));
    };
    if spec.rotation != [0.0; 3] {
        return Err(bad(
            "grains[0].shape.surface.rotation",
            "the ellipsoid must be axis-aligned (it is loaded along z)".into(),
        ));
    }
    // the surface as the import reads it: units, scale, checks, origin (before rotation)
    let points = match crate::mesh::import::prepare(spec, false) {
        Ok((Prepared::Surface(s), _)) => s.points,
        Ok((Prepared::Volume(_), _)) => {
            return Err(bad(
                "grains[0].shape.surface.file",
                "needs a surface file, not a volume mesh".into(),
            ))
        }
        Err(e) => return Err(e.for_grain(&file, 0).into()),
    };
    let fit = fit_axis_aligned_ellipsoid(&points).filter(|f| f.1 <= ELLIPSOID_TOLERANCE);
    let Some((semi_axes, _)) = fit else {
        return Err(bad(
            "grains[0].shape.surface.file",
            format!(
                "{} is not an ellipsoid centred on its origin with axes along x, y, z (|x²/A² + y²/B² + z²/C² − 1| > {ELLIPSOID_TOLERANCE})",
                spec.file
            ),
        ));
    };
    // to 6 significant digits: binary STL stores f32 (~7 digits), and the rounding makes
    // the semi-axes of a written STL those it was written for
    let semi_axes = semi_axes.map(|x| format!("{x:.5e}").parse().unwrap_or(x));
    let [a, b, c] = semi_axes;
    if c > a.min(b) {
        return Err(bad(
            "grains[0].shape.surface.file",
            format!(
                "semi-axes {} × {} × {} m: the case presses along z, which must be the shortest axis (pressed along a longer one, the grain tips over between frictionless plates)",
                num(a),
                num(b),
                num(c)
            ),
        ));
    }
    let m = &scene.materials[&g.material];
    let material = ElasticParameters {
        youngs_modulus: m.youngs_modulus,
        poisson_ratio: m.poisson_ratio,
        density: m.density,
    };
    let theory = EllipticHertz::new(a * a / c, b * b / c, material.plane_strain_modulus());
    let inputs = SceneInputs {
        file: file.clone(),
        material_name: g.material.clone(),
        material,
        material_extra: loaded.material_extra_fields(&g.material),
        radius: theory.equivalent_radius(),
        friction: 0.0,
    };
    Ok(Setup {
        inputs,
        semi_axes,
        theory,
    })
}

/// The scene of one run and the STL it reads (written into `dir` as [`STL_NAME`]), for tip
/// facets of `tip_seeding`; returns the scene text and the STL's facet count.
fn write_run_files(
    setup: &Setup,
    p: &HertzEllipsoidParams,
    tip_seeding: f64,
    dir: &Path,
) -> Result<(String, usize)> {
    let surface = tip_refined_surface(setup, p, tip_seeding)?;
    std::fs::create_dir_all(dir).map_err(|e| MufeError::Io(format!("{}: {e}", dir.display())))?;
    let stl = dir.join(STL_NAME);
    let mut out = std::io::BufWriter::new(
        std::fs::File::create(&stl)
            .map_err(|e| MufeError::Io(format!("{}: {e}", stl.display())))?,
    );
    formats::write_stl_binary(&surface, &mut out)
        .map_err(|e| MufeError::Io(format!("{}: {e}", stl.display())))?;
    drop(out);
    let facets = surface.facets.len();
    Ok((scene_text(setup, p, tip_seeding, facets), facets))
}

/// Points of the exponential plate speed.
const DRIVE_POINTS: usize = 48;

/// The scene of a run whose STL (`STL_NAME`, beside the scene) has `facets` facets.
fn scene_text(setup: &Setup, p: &HertzEllipsoidParams, tip_seeding: f64, facets: usize) -> String {
    let stl_ref = STL_NAME;
    let u = setup.inputs.units();
    let h = &setup.theory;
    let re = setup.equivalent_radius();
    let [a, b, c] = setup.semi_axes;
    let f_end = h.force_at_equivalent_radius(WINDOW.1 * re);
    // a little beyond the window: the finite body is stiffer than the half-space
    let delta_end = 1.03 * h.approach(f_end);
    let (tau, delta0) = (p.tau * u.time, p.delta0 * re);
    let duration = tau * (1.0 + delta_end / delta0).ln();
    let speeds: Vec<(f64, f64)> = (0..=DRIVE_POINTS)
        .map(|k| {
            let t = duration * k as f64 / DRIVE_POINTS as f64;
            (t, delta0 / tau * (t / tau).exp())
        })
        .collect();
    let history = |sign: f64| {
        let times: Vec<String> = speeds.iter().map(|s| format!("{:.9e}", s.0)).collect();
        let values: Vec<String> = speeds
            .iter()
            .map(|s| format!("[0.0, 0.0, {:.6e}]", sign * s.1))
            .collect();
        format!(
            "{{ times = [{}], values = [{}] }}",
            times.join(", "),
            values.join(", ")
        )
    };
    format!(
        r#"# Hertz elliptical contact: an ellipsoid (semi-axes {a_mm:.4} × {b_mm:.4} × {c_mm:.4} mm, read from
# {stl_ref}) squeezed along z between two rigid frictionless plates (docs/THEORY.md §1b).
# Tip radii R1 = A²/C = {r1_mm:.4} mm, R2 = B²/C = {r2_mm:.4} mm: the contact is an ellipse with
# b/a = {ratio:.4}. The plates start at the tips and each travels δ = δ0 (e^(t/τ) − 1),
# τ = {tau_us:.4} µs, δ0 = {d0_um:.4} µm, to {dend_um:.4} µm (F ≈ {f_end:.4} N, √(ab)/R_e = {w1}).
# STL: {facets} facets, {tip_um:.3} µm at the tips (MR = s/(2R_e) = {mr:.4}), {bulk_um:.1} µm elsewhere.
#
# How to run:  mufe validate {NAME}        (sweep of meshing ratios, plots, JSON)
#              mufe run jobs/validation/{NAME}.toml --out out/{NAME}   (one run)
# Generated by `mufe validate --write-scenes DIR` (src/validate/{NAME}.rs); `mufe validate`
# reads the material and the ellipsoid of this file (after --set) and writes a new STL of
# the same ellipsoid with fine tips for each meshing ratio.

[simulation]
duration = {duration:.6e}
# mass scaling of the fine tip elements only; quasi-static (KE/IE is reported)
target_dt = {target_dt:.3e}

{material}
[[grains]]
name = "ellipsoid"
material = "{mat}"
centre = [0.0, 0.0, 0.0]
# the STL is fine at the tips; refine[] also makes the elements below them fine
shape = {{ surface = {{ file = "{stl_ref}", units = "m", seeding = {bulk:.4e}, origin = "file", refine = [
    {{ point = [0.0, 0.0, {c:.9e}], seeding = {tip:.4e}, radius = {tip_r:.4e}, growth = {growth:?} }},
    {{ point = [0.0, 0.0, {neg_c:.9e}], seeding = {tip:.4e}, radius = {tip_r:.4e}, growth = {growth:?} }},
] }} }}

[contact]
friction = 0.0

[[walls]]
name = "top"
point = [0.0, 0.0, {c:.9e}]
normal = [0.0, 0.0, -1.0]
velocity = {v_top}

[[walls]]
name = "bottom"
point = [0.0, 0.0, {neg_c:.9e}]
normal = [0.0, 0.0, 1.0]
velocity = {v_bottom}

[output]
history_interval = {hist:.3e}
frames = false
"#,
        a_mm = a * 1e3,
        b_mm = b * 1e3,
        c_mm = c * 1e3,
        r1_mm = h.r1 * 1e3,
        r2_mm = h.r2 * 1e3,
        ratio = h.axis_ratio(),
        tau_us = tau * 1e6,
        d0_um = delta0 * 1e6,
        dend_um = delta_end * 1e6,
        w1 = WINDOW.1,
        tip_um = tip_seeding * 1e6,
        mr = tip_seeding / (2.0 * re),
        bulk_um = p.seeding * re * 1e6,
        target_dt = p.target_dt * u.time,
        material = setup.inputs.material_block(),
        mat = setup.inputs.material_name,
        bulk = p.seeding * re,
        tip = tip_seeding,
        tip_r = p.tip_radius * re,
        growth = p.growth,
        neg_c = -c,
        v_top = history(-1.0),
        v_bottom = history(1.0),
        hist = p.history_interval * u.time,
    )
}

/// Running sums of the nodal contact forces of one plate: Σf, Σf x, Σf y, Σf x², Σf y².
#[derive(Default, Clone, Copy)]
struct PlateMoments([f64; 5]);

impl PlateMoments {
    fn add(&mut self, f: f64, x: f64, y: f64) {
        let s = &mut self.0;
        s[0] += f;
        s[1] += f * x;
        s[2] += f * y;
        s[3] += f * x * x;
        s[4] += f * y * y;
    }
    /// Semi-axes along x and y of the Hertz ellipse with these moments (a² = 5⟨x²⟩).
    fn semi_axes(&self) -> Option<(f64, f64)> {
        let s = &self.0;
        (s[0] > 0.0).then(|| {
            let (mx, my) = (s[1] / s[0], s[2] / s[0]);
            (
                (5.0 * (s[3] / s[0] - mx * mx)).max(0.0).sqrt(),
                (5.0 * (s[4] / s[0] - my * my)).max(0.0).sqrt(),
            )
        })
    }
}

pub struct HertzEllipsoidCase;

impl Case for HertzEllipsoidCase {
    fn name(&self) -> &'static str {
        NAME
    }

    fn shipped_scene(&self) -> &'static str {
        SCENE
    }

    fn sweep_mrs(&self) -> Vec<f64> {
        vec![0.0028, 0.0019, 0.0013, 0.0009]
    }

    fn quick_mr(&self) -> f64 {
        QUICK_MR
    }

    fn full_target(&self) -> f64 {
        TARGET
    }

    fn write_scene_files(
        &self,
        dir: &Path,
        overrides: &[String],
        params: &Params,
    ) -> Result<Vec<PathBuf>> {
        Ok(vec![
            write_shipped_files(dir, overrides, params)?,
            dir.join(STL_NAME),
        ])
    }

    /// The shipped scene at the quick MR (its STL: [`write_shipped_files`]).
    fn generated_scene(&self, overrides: &[String], params: &Params) -> Result<String> {
        let setup = load_setup(overrides)?;
        let s = QUICK_MR * 2.0 * setup.equivalent_radius();
        Ok(scene_text(
            &setup,
            &params.hertz_ellipsoid,
            s,
            tip_refined_surface(&setup, &params.hertz_ellipsoid, s)?
                .facets
                .len(),
        ))
    }

    fn run(
        &self,
        mr: f64,
        quick: bool,
        overrides: &[String],
        params: &Params,
        record: Option<&Recorder>,
    ) -> Result<CaseOutcome> {
        let setup = load_setup(overrides)?;
        let p = &params.hertz_ellipsoid;
        let re = setup.equivalent_radius();
        let tip_seeding = mr * 2.0 * re;
        let dir: PathBuf = match record {
            Some(r) => r.run_dir(NAME, mr),
            None => std::env::temp_dir().join(format!("mufe-{NAME}-{}-mr{mr}", std::process::id())),
        };
        let (text, stl_facets) = write_run_files(&setup, p, tip_seeding, &dir)?;
        let scene_path = dir.join(format!("{NAME}.toml"));
        std::fs::write(&scene_path, &text)
            .map_err(|e| MufeError::Io(format!("{}: {e}", scene_path.display())))?;
        // the overrides are in the generated scene already (material, and the STL's size):
        // applied again, a scale would count twice
        let loaded = parse_scene(&scene_path.display().to_string(), &text, &[])?;
        let mut solver = case_solver(&loaded)?;
        let mesh = recorded_mesh(record, &loaded)?;
        let mut output = CaseOutput::open(record, NAME, mr, &loaded, mesh.as_ref(), &solver)?;
        let h = setup.theory;
        let c = setup.semi_axes[2];
        let z =
            |f: fn(f64, f64) -> f64, init: f64| solver.state.x.iter().map(|q| q[2]).fold(init, f);
        let (gap_top, gap_bottom) = (
            c - z(f64::max, f64::NEG_INFINITY),
            z(f64::min, f64::INFINITY) + c,
        );
        let delta_end = h.approach(h.force_at_equivalent_radius(WINDOW.1 * re));
        let sample_every =
            ((loaded.scene.output.history_interval.unwrap_or(5e-8) / solver.model.dt).round()
                as u64)
                .max(1);
        let max_steps = (loaded.scene.simulation.duration / solver.model.dt).ceil() as u64;
        let mut probe = Probe::new(&solver);
        let mut moments = [PlateMoments::default(); 2];
        // (δ, F, b/a measured, √(ab) measured, KE/IE)
        let mut samples: Vec<(f64, f64, f64, f64, f64)> = Vec::new();
        while solver.state.step < max_steps {
            solver.step()?;
            output.after_step(&solver, solver.state.step == max_steps)?;
            for &(node, f) in &solver.scratch.contact.wall_node_force {
                let x = solver.state.x[node as usize];
                moments[usize::from(x[2] < 0.0)].add(f[2].abs(), x[0], x[1]);
            }
            if solver.state.step % sample_every != 0 {
                continue;
            }
            probe.sample(&solver);
            let d_top = -probe.get("top_displacement_z")? - gap_top;
            let d_bottom = probe.get("bottom_displacement_z")? - gap_bottom;
            let delta = 0.5 * (d_top + d_bottom);
            let force =
                0.5 * (probe.get("top_force_z")?.abs() + probe.get("bottom_force_z")?.abs());
            let axes: Vec<(f64, f64)> = moments.iter().filter_map(|m| m.semi_axes()).collect();
            moments = [PlateMoments::default(); 2];
            let (mut ratio, mut size) = (f64::NAN, f64::NAN);
            if axes.len() == 2 {
                let r: f64 = axes.iter().map(|&(x, y)| x.min(y) / x.max(y)).sum::<f64>() / 2.0;
                let s: f64 = axes.iter().map(|&(x, y)| (x * y).sqrt()).sum::<f64>() / 2.0;
                (ratio, size) = (r, s);
            }
            let ie = probe.get("internal_energy")?;
            samples.push((
                delta,
                force,
                ratio,
                size,
                probe.get("kinetic_energy")? / ie.max(1e-300),
            ));
            if delta >= delta_end {
                break;
            }
        }
        let (mut err_force, mut err_ratio, mut err_size, mut ke_ie) =
            (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
        let (mut curve, mut error_curve, mut shape_curve) = (Vec::new(), Vec::new(), Vec::new());
        let mut in_window = 0;
        for &(delta, force, ratio, size, kinetic) in &samples {
            if delta <= 0.0 {
                continue;
            }
            let f_ref = h.force(delta);
            curve.push((delta * 1e6, force));
            let (a_ref, b_ref) = h.semi_axes(f_ref);
            let ae = (a_ref * b_ref).sqrt() / re;
            if !(WINDOW.0..=WINDOW.1).contains(&ae) {
                continue;
            }
            in_window += 1;
            err_force = err_force.max((force - f_ref).abs() / f_ref);
            err_ratio = err_ratio.max((ratio / h.axis_ratio() - 1.0).abs());
            err_size = err_size.max((size / (a_ref * b_ref).sqrt() - 1.0).abs());
            ke_ie = ke_ie.max(kinetic);
            error_curve.push((ae, 100.0 * (force - f_ref) / f_ref));
            shape_curve.push(json!([ae, ratio]));
        }
        if in_window < 5 {
            return Err(MufeError::Run(format!(
                "{NAME} at MR {mr}: only {in_window} samples in the window √(ab)/R_e = {} … {}; lengthen simulation.duration",
                WINDOW.0, WINDOW.1
            )));
        }
        let err = if err_ratio.is_nan() {
            f64::INFINITY
        } else {
            err_force.max(err_ratio)
        };
        let target = self.target(quick);
        let mut details = serde_json::Map::new();
        details.insert("error_force".into(), json!(err_force));
        details.insert("error_axis_ratio".into(), json!(err_ratio));
        details.insert("error_equivalent_contact_radius".into(), json!(err_size));
        details.insert("axis_ratio_theory".into(), json!(h.axis_ratio()));
        details.insert("axis_ratio_fe".into(), json!(shape_curve));
        details.insert("semi_axes_m".into(), json!(setup.semi_axes));
        details.insert("tip_radii_m".into(), json!([h.r1, h.r2]));
        details.insert("tip_seeding_m".into(), json!(tip_seeding));
        details.insert("max_kinetic_over_internal".into(), json!(ke_ie));
        details.insert("samples_in_window".into(), json!(in_window));
        details.insert(
            "window_force_n".into(),
            json!([
                h.force_at_equivalent_radius(WINDOW.0 * re),
                h.force_at_equivalent_radius(WINDOW.1 * re)
            ]),
        );
        details.insert(
            "finite_body_estimate".into(),
            json!(finite_body_estimate(
                &setup.inputs.material,
                c,
                [WINDOW.0 * re, WINDOW.1 * re]
            )),
        );
        details.insert("stl_facets".into(), json!(stl_facets));
        details.insert("scene".into(), super::runner::scene_details(&setup.inputs));
        details.insert(
            "added_mass_fraction".into(),
            json!(solver.model.added_mass / solver.model.total_physical_mass()),
        );
        output.finish(&solver, &mut details)?;
        if record.is_none() {
            let _ = std::fs::remove_dir_all(&dir);
        }
        Ok(CaseOutcome {
            case: NAME.into(),
            mr,
            elements: solver.model.num_elements(),
            steps: solver.state.step,
            wall_s: 0.0,
            error: err,
            target,
            pass: err <= target,
            details,
            curve,
            error_curve,
        })
    }

    fn error_axis(&self) -> (&'static str, Scale) {
        (
            "equivalent contact radius of the theory force √(ab)/R_e",
            Scale::Linear,
        )
    }

    fn draw_plots(&self, outcomes: &[CaseOutcome], out: &Path) -> Result<()> {
        super::runner::draw_curve_plots(self, outcomes, out)?;
        let theory = outcomes
            .iter()
            .find_map(|o| o.details.get("axis_ratio_theory").and_then(|v| v.as_f64()));
        let mut series: Vec<Series> = theory
            .map(|r| Series {
                label: "elliptical Hertz (THEORY §1b)".into(),
                points: vec![(WINDOW.0, r), (WINDOW.1, r)],
                theory: true,
            })
            .into_iter()
            .collect();
        for o in outcomes {
            let points = o
                .details
                .get("axis_ratio_fe")
                .and_then(|v| v.as_array())
                .map(|a| {
                    a.iter()
                        .filter_map(|p| Some((p.get(0)?.as_f64()?, p.get(1)?.as_f64()?)))
                        .collect()
                })
                .unwrap_or_default();
            series.push(Series {
                label: format!("FE, MR = {:.4} ({} elements)", o.mr, o.elements),
                points,
                theory: false,
            });
        }
        let png = out.join(format!("{NAME}_axis_ratio.png"));
        plot::draw(
            &png,
            &Plot {
                title: "contact ellipse axis ratio b/a (second moments of the plate forces)",
                x_label: "equivalent contact radius of the theory force √(ab)/R_e",
                y_label: "b/a",
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series,
            },
        )
        .map_err(|e| MufeError::Io(format!("{}: {e}", png.display())))
    }

    fn plot(&self, outcomes: &[CaseOutcome]) -> (Plot<'static>, Vec<Series>) {
        let mut series = Vec::new();
        // the theory of the runs' ellipsoid and material
        if let Some(o) = outcomes.first() {
            let radii = o
                .details
                .get("tip_radii_m")
                .and_then(|v| v.as_array())
                .and_then(|a| Some((a.first()?.as_f64()?, a.get(1)?.as_f64()?)));
            if let (Some((r1, r2)), Some((m, _, _))) = (radii, super::runner::outcome_scene(o)) {
                let h = EllipticHertz::new(r1, r2, m.plane_strain_modulus());
                let d_max = outcomes
                    .iter()
                    .flat_map(|o| o.curve.iter().map(|p| p.0))
                    .fold(0.0, f64::max)
                    * 1e-6;
                let d_min = d_max * 1e-2;
                let pts = (0..100)
                    .map(|i| {
                        let d = d_min * (d_max / d_min).powf(i as f64 / 99.0);
                        (d * 1e6, h.force(d))
                    })
                    .collect();
                series.push(Series {
                    label: "elliptical Hertz, half-space (THEORY §1b)".into(),
                    points: pts,
                    theory: true,
                });
            }
        }
        (
            Plot {
                title: "Hertz: ellipsoid between rigid plates",
                x_label: "approach of each plate δ (µm)",
                y_label: "plate force F (N)",
                x_scale: Scale::Log,
                y_scale: Scale::Log,
                series: vec![],
            },
            series,
        )
    }
}

/// How much stiffer than half-space Hertz a sphere of radius `depth` between plates is at
/// contact radii of the window ends (F_ref/F_H − 1, finite-sphere table at the scene's ν):
/// the size of the finite-body effect for a body of that depth.
fn finite_body_estimate(
    material: &ElasticParameters,
    depth: f64,
    sizes: [f64; 2],
) -> Option<[f64; 2]> {
    let table = FiniteSphereTable::load().at_poisson_ratio(material.poisson_ratio)?;
    let hertz = Hertz::sphere_on_flat(material, depth);
    let at = |a: f64| {
        let delta = a * a / depth;
        Some(table.force(material, depth, delta)? / hertz.force(delta) - 1.0)
    };
    Some([at(sizes[0])?, at(sizes[1])?])
}

/// The case's ellipsoid with facets of `tip_seeding` at its tips (bulk and patch sizes
/// from `p`, in units of R_e).
fn tip_refined_surface(
    setup: &Setup,
    p: &HertzEllipsoidParams,
    tip_seeding: f64,
) -> Result<crate::mesh::import::Surface> {
    let re = setup.equivalent_radius();
    TipRefinedEllipsoid {
        semi_axes: setup.semi_axes,
        seeding: p.seeding * re,
        tip_seeding,
        tip_radius: p.tip_radius * re,
        growth: p.growth,
    }
    .surface()
    .map_err(|e| MufeError::Run(format!("{NAME}: {e}")))
}

/// Writes the case scene and its STL (at the quick MR) into `dir` for the material and
/// ellipsoid of the case scene after `overrides`: `jobs/validation/hertz_ellipsoid.*`
/// are this output for the shipped glass ellipsoid.
pub fn write_shipped_files(dir: &Path, overrides: &[String], params: &Params) -> Result<PathBuf> {
    let setup = load_setup(overrides)?;
    let s = QUICK_MR * 2.0 * setup.equivalent_radius();
    let (text, _) = write_run_files(&setup, &params.hertz_ellipsoid, s, dir)?;
    let path = dir.join(format!("{NAME}.toml"));
    std::fs::write(&path, text).map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))?;
    Ok(path)
}
