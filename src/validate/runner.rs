//! Running validation cases over meshing ratios: table, `validation.json`, PNG plots.

use super::record::{Recorder, BALANCE_TOLERANCE};
use super::scenes::{case_scene, Params, SceneInputs};
use crate::domain::Domain;
use crate::driver::{history_columns, history_row};
use crate::error::{InputError, MufeError, Result};
use crate::io::plot::{self, Plot, Scale, Series};
use crate::scene::{parse_scene, LoadedScene};
use crate::solver::build_solver;
use crate::solver::Solver;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One row of `validation.json` (the fields of the printed table first, then case extras).
#[derive(Debug, Clone, Serialize)]
pub struct CaseOutcome {
    pub case: String,
    /// Meshing ratio at the contact, s/(2R).
    pub mr: f64,
    pub elements: usize,
    pub steps: u64,
    pub wall_s: f64,
    /// The case's documented error metric (fraction).
    pub error: f64,
    pub target: f64,
    pub pass: bool,
    /// Case-specific extras (distance from half-space Hertz, max penetration / δ,
    /// max KE/IE, normal-force drift, ...).
    pub details: serde_json::Map<String, serde_json::Value>,
    /// The FE curve (x, y) in the case's plot units.
    #[serde(skip)]
    pub curve: Vec<(f64, f64)>,
    /// Signed relative error along the loading range (x in the case's load units, y in %),
    /// drawn as `<case>_error.png` when present.
    #[serde(skip)]
    pub error_curve: Vec<(f64, f64)>,
}

/// A validation case.
pub trait Case {
    fn name(&self) -> &'static str;
    /// The shipped scene text (`jobs/validation/<case>.toml`).
    fn shipped_scene(&self) -> &'static str;
    /// Meshing ratios of the full sweep, coarse to fine.
    fn sweep_mrs(&self) -> Vec<f64>;
    /// The one meshing ratio of the quick run (`--quick`, `cargo test`).
    fn quick_mr(&self) -> f64;
    /// Meshing ratios given with `--mr` must lie in (0, this): 1 where MR is the element
    /// size over the sphere radius.
    fn max_mr(&self) -> f64 {
        1.0
    }
    /// Default meshing ratios at the contact (full sweep, or quick).
    fn default_mrs(&self, quick: bool) -> Vec<f64> {
        if quick {
            vec![self.quick_mr()]
        } else {
            self.sweep_mrs()
        }
    }
    /// Accuracy target (fraction) of the full sweep's finest meshing ratio.
    fn full_target(&self) -> f64;
    /// The target of a run: the full target, or [`super::QUICK_TOLERANCE_FACTOR`] times it
    /// for the quick (coarse) runs.
    fn target(&self, quick: bool) -> f64 {
        if quick {
            super::QUICK_TOLERANCE_FACTOR * self.full_target()
        } else {
            self.full_target()
        }
    }
    /// Runs at one meshing ratio: the case scene (after `overrides`) gives the material,
    /// radius and friction, the scene run is generated from them with `params`. With a
    /// recorder the run also writes `results.h5` and `energy.png` ([`super::record`]).
    fn run(
        &self,
        mr: f64,
        quick: bool,
        overrides: &[String],
        params: &Params,
        record: Option<&Recorder>,
    ) -> Result<CaseOutcome>;
    /// Every run of one `mufe validate` call, each outcome handed to `report` (which checks
    /// and prints it) as soon as it is done: by default one [`Case::run`] per meshing
    /// ratio; a case sweeping another variable (friction) overrides it.
    fn run_sweep(
        &self,
        mrs: &[f64],
        quick: bool,
        overrides: &[String],
        params: &Params,
        record: Option<&Recorder>,
        report: &mut dyn FnMut(&mut CaseOutcome),
    ) -> Result<Vec<CaseOutcome>> {
        let mut outcomes = Vec::new();
        for &mr in mrs {
            let t0 = Instant::now();
            let mut o = self.run(mr, quick, overrides, params, record)?;
            o.wall_s = t0.elapsed().as_secs_f64();
            report(&mut o);
            outcomes.push(o);
        }
        Ok(outcomes)
    }
    /// Draws the case's plots into `out`: by default `<case>.png` (FE curves over the
    /// theory of [`Case::plot`]) and, where outcomes carry one, `<case>_error.png`.
    fn draw_plots(&self, outcomes: &[CaseOutcome], out: &Path) -> Result<()> {
        draw_curve_plots(self, outcomes, out)
    }
    /// The scene a run of this case uses (`mufe validate --write-scenes`), generated from
    /// the case scene after `overrides`.
    fn generated_scene(&self, overrides: &[String], params: &Params) -> Result<String> {
        let inputs = case_inputs(self.name(), self.shipped_scene(), overrides)?;
        Ok(case_scene(self.name(), &inputs, params)?)
    }
    /// The name `--write-scenes` gives the generated scene: `<case>.toml`, as the shipped
    /// scene it reproduces. A case whose shipped scene is an input it builds its run scene
    /// from names it otherwise, so that writing into jobs/validation never replaces an input.
    fn generated_file_name(&self) -> String {
        format!("{}.toml", self.name())
    }
    /// Writes the generated scene (and any file it reads) into `dir`
    /// (`mufe validate --write-scenes`); returns the files written.
    fn write_scene_files(
        &self,
        dir: &Path,
        overrides: &[String],
        params: &Params,
    ) -> Result<Vec<PathBuf>> {
        let text = self.generated_scene(overrides, params)?;
        // the written file must parse as it stands
        parse_scene(self.name(), &text, &[])?;
        let path = dir.join(self.generated_file_name());
        std::fs::write(&path, text)
            .map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))?;
        Ok(vec![path])
    }
    /// Label and scale of the x axis of the error plot.
    fn error_axis(&self) -> (&'static str, Scale) {
        ("load", Scale::Linear)
    }
    /// Theory curve over the range of the given outcomes, and the plot axes.
    fn plot(&self, outcomes: &[CaseOutcome]) -> (Plot<'static>, Vec<Series>);
}

/// Loads a case scene (embedded copy of `jobs/validation/<case>.toml`) with overrides.
/// With the environment variable `MUFE_VALIDATION_SCENES=DIR` set, `DIR/<case>.toml` is
/// read instead. Only its material, radius and friction matter to `mufe validate`: the
/// scene run is generated from them ([`generated_case_scene`]).
pub fn load_case_scene(name: &str, text: &str, overrides: &[String]) -> Result<LoadedScene> {
    if let Some(dir) = std::env::var_os("MUFE_VALIDATION_SCENES") {
        let path = Path::new(&dir).join(format!("{name}.toml"));
        let text = std::fs::read_to_string(&path).map_err(|e| {
            crate::error::InputError::new(
                path.display().to_string(),
                "file",
                format!("cannot read the case scene (MUFE_VALIDATION_SCENES): {e}"),
            )
        })?;
        return Ok(parse_scene(&path.display().to_string(), &text, overrides)?);
    }
    Ok(parse_scene(
        &format!("jobs/validation/{name}.toml"),
        text,
        overrides,
    )?)
}

/// Material, radius and friction of a case scene after `overrides` (see
/// [`load_case_scene`]).
pub fn case_inputs(name: &str, shipped: &str, overrides: &[String]) -> Result<SceneInputs> {
    let base = load_case_scene(name, shipped, overrides)?;
    Ok(SceneInputs::from_scene(name, &base, overrides)?)
}

/// The scene a case runs: the case scene is loaded with `overrides` (see
/// [`load_case_scene`]), its material, radius and friction are read, the full scene is
/// generated from them ([`super::scenes`]) and parsed with `sets` (the meshing ratio's
/// seedings) and then `overrides` applied again (so an override of any generated field
/// still wins). Returns the scene and the inputs it was generated from.
pub fn generated_case_scene(
    name: &str,
    shipped: &str,
    overrides: &[String],
    params: &Params,
    sets: &[String],
) -> Result<(LoadedScene, SceneInputs)> {
    let inputs = case_inputs(name, shipped, overrides)?;
    let text = case_scene(name, &inputs, params)?;
    let mut all = sets.to_vec();
    all.extend_from_slice(overrides);
    let loaded = parse_scene(&format!("{} (as generated)", inputs.file), &text, &all)?;
    Ok((loaded, inputs))
}

/// The generation inputs of a run, for `validation.json` (`details.scene`).
pub fn scene_details(inputs: &SceneInputs) -> serde_json::Value {
    let m = &inputs.material;
    serde_json::json!({
        "file": inputs.file,
        "youngs_modulus_pa": m.youngs_modulus,
        "poisson_ratio": m.poisson_ratio,
        "density_kg_m3": m.density,
        "radius_m": inputs.radius,
        "friction": inputs.friction,
    })
}

/// Material, radius and friction of an outcome (from [`scene_details`]).
pub fn outcome_scene(o: &CaseOutcome) -> Option<(crate::material::ElasticParameters, f64, f64)> {
    let s = o.details.get("scene")?;
    let f = |k: &str| s.get(k).and_then(|v| v.as_f64());
    Some((
        crate::material::ElasticParameters {
            youngs_modulus: f("youngs_modulus_pa")?,
            poisson_ratio: f("poisson_ratio")?,
            density: f("density_kg_m3")?,
        },
        f("radius_m")?,
        f("friction")?,
    ))
}

/// The file a case whose shipped scene is an input writes its run scene to
/// ([`Case::generated_file_name`]).
pub fn drive_file_name(case: &str) -> String {
    format!("{case}_drive.toml")
}

/// The header of the run scene in [`drive_file_name`]: what it is, where it comes from,
/// how to run it.
pub fn drive_scene_header(case: &str, read: &str, mr: f64) -> String {
    format!(
        "# Generated by `mufe validate --write-scenes DIR` (src/validate/{case}.rs)\n\
         # from {read} of jobs/validation/{case}.toml (edit there, or give --set):\n\
         # the scene `mufe validate {case}` runs at MR {mr}, drive and boundaries included.\n\
         # Run it on its own with `mufe run {}`.\n\n",
        drive_file_name(case)
    )
}

/// Writes the generated scenes of `cases` for the material, radius and friction of the
/// case scenes after `overrides` (the shipped files with no overrides) to `dir`.
pub fn write_scenes(
    cases: &[Box<dyn Case>],
    dir: &Path,
    overrides: &[String],
    params: &Params,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| MufeError::Io(format!("{}: cannot create directory: {e}", dir.display())))?;
    let mut written = Vec::new();
    for case in cases {
        written.extend(case.write_scene_files(dir, overrides, params)?);
    }
    Ok(written)
}

/// Reads named history columns from a solver while it runs.
pub struct Probe {
    names: Vec<String>,
    row: Vec<f64>,
}

impl Probe {
    pub fn new(solver: &Solver) -> Self {
        Self {
            names: history_columns(solver)
                .into_iter()
                .map(|c| c.name)
                .collect(),
            row: Vec::new(),
        }
    }
    /// Refreshes the values from the solver's current state.
    pub fn sample(&mut self, solver: &Solver) {
        history_row(solver, &mut self.row);
    }
    /// Value of a column (after `sample`).
    pub fn get(&self, name: &str) -> Result<f64> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.row[i])
            .ok_or_else(|| MufeError::Run(format!("validation: no history column '{name}'")))
    }
}

/// Builds the solver of a case scene.
pub fn case_solver(loaded: &LoadedScene) -> Result<Solver> {
    build_solver(loaded)
}

/// Runs the given cases over their meshing ratios, prints the table, writes
/// `out/validation.json` and the plots. Returns all outcomes.
pub fn run_cases(
    cases: &[Box<dyn Case>],
    mrs: Option<&[f64]>,
    quick: bool,
    out: &Path,
    overrides: &[String],
    params: &Params,
    domain: &Domain,
) -> Result<Vec<CaseOutcome>> {
    std::fs::create_dir_all(out)
        .map_err(|e| MufeError::Io(format!("{}: cannot create directory: {e}", out.display())))?;
    let recorder = Recorder {
        domain,
        root: out.to_path_buf(),
    };
    println!(
        "{:<15} {:>8} {:>9} {:>8} {:>9} {:>9} {:>8} {:>9} {:>5}",
        "case", "MR", "elements", "steps", "wall s", "error", "target", "balance", "pass"
    );
    let mut all = Vec::new();
    for case in cases {
        let list = mrs
            .map(|m| m.to_vec())
            .unwrap_or_else(|| case.default_mrs(quick));
        let outcomes = case.run_sweep(
            &list,
            quick,
            overrides,
            params,
            Some(&recorder),
            &mut |o: &mut CaseOutcome| {
                let balance = balance_error(o);
                // every case keeps its energy ledger closed, whatever its curve metric
                o.pass &= balance <= BALANCE_TOLERANCE;
                println!(
                    "{:<15} {:>8.4} {:>9} {:>8} {:>9.1} {:>9} {:>8} {:>9} {:>5}",
                    o.case,
                    o.mr,
                    o.elements,
                    o.steps,
                    o.wall_s,
                    percent(o.error),
                    percent(o.target),
                    percent(balance),
                    if o.pass { "yes" } else { "NO" }
                );
            },
        )?;
        case.draw_plots(&outcomes, out)?;
        write_curves(&out.join(format!("{}_curves.csv", case.name())), &outcomes)?;
        all.extend(outcomes);
    }
    write_json(&out.join("validation.json"), &all)?;
    speed_vs_error_plot(&out.join("speed_vs_error.png"), &all)?;
    println!(
        "wrote {}, {}, one PNG per case, and DIR/<case>/mr_<MR>/results.h5 + energy.png per run",
        out.join("validation.json").display(),
        out.join("speed_vs_error.png").display()
    );
    Ok(all)
}

/// The default plots of a case (see [`Case::draw_plots`]).
pub fn draw_curve_plots<C: Case + ?Sized>(
    case: &C,
    outcomes: &[CaseOutcome],
    out: &Path,
) -> Result<()> {
    let (mut p, theory) = case.plot(outcomes);
    let mut series = theory;
    for o in outcomes {
        series.push(Series {
            label: format!("FE, MR = {:.4} ({} elements)", o.mr, o.elements),
            points: o.curve.clone(),
            theory: false,
        });
    }
    p.series = series;
    let png = out.join(format!("{}.png", case.name()));
    plot::draw(&png, &p).map_err(|e| MufeError::Io(format!("{}: {e}", png.display())))?;
    if outcomes.iter().any(|o| !o.error_curve.is_empty()) {
        let png = out.join(format!("{}_error.png", case.name()));
        let series = outcomes
            .iter()
            .map(|o| Series {
                label: format!("MR = {:.4}", o.mr),
                points: o.error_curve.clone(),
                theory: false,
            })
            .collect();
        let (x_label, x_scale) = case.error_axis();
        plot::draw(
            &png,
            &Plot {
                title: "signed error vs reference along the loading",
                x_label,
                y_label: "(FE − reference)/reference (%)",
                x_scale,
                y_scale: Scale::Linear,
                series,
            },
        )
        .map_err(|e| MufeError::Io(format!("{}: {e}", png.display())))?;
    }
    Ok(())
}

/// The largest energy-balance drift of a run ([`super::record::CaseOutput`]); infinite
/// when a case did not report it.
pub fn balance_error(o: &CaseOutcome) -> f64 {
    o.details
        .get("energy_balance_error")
        .and_then(|v| v.as_f64())
        .unwrap_or(f64::INFINITY)
}

/// A fraction as a percentage, in scientific notation below 0.01 %.
fn percent(fraction: f64) -> String {
    let p = 100.0 * fraction;
    if p != 0.0 && p.abs() < 0.01 {
        format!("{p:.1e}%")
    } else {
        format!("{p:.2}%")
    }
}

fn write_json(path: &PathBuf, outcomes: &[CaseOutcome]) -> Result<()> {
    let text = serde_json::to_string_pretty(outcomes).map_err(|e| MufeError::Io(e.to_string()))?;
    std::fs::write(path, text).map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))
}

/// The FE curves (plot units) and signed error curves of one case, for re-plotting.
fn write_curves(path: &Path, outcomes: &[CaseOutcome]) -> Result<()> {
    let mut text = String::from("# series,mr,x,y  (series: curve = FE curve in plot units, error = signed error % vs load)\n");
    for o in outcomes {
        for (name, pts) in [("curve", &o.curve), ("error", &o.error_curve)] {
            for p in pts.iter() {
                text.push_str(&format!("{name},{},{:.9e},{:.9e}\n", o.mr, p.0, p.1));
            }
        }
    }
    std::fs::write(path, text).map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))
}

/// Kinetic energy of the motion relative to each grain's rigid-body velocity field (from
/// its linear and angular momentum): the vibration part of ALLKE, without the energy of a
/// driven grain's rigid translation or rotation (J).
pub fn deformation_kinetic_energy(solver: &Solver) -> f64 {
    use nalgebra::{Matrix3, Vector3};
    let (model, state) = (&solver.model, &solver.state);
    let mut total = 0.0;
    for g in &model.grains {
        let nodes = g.nodes.clone();
        let (mut m_sum, mut c, mut p) = (0.0, Vector3::zeros(), Vector3::zeros());
        for n in nodes.clone() {
            let m = model.mass[n];
            m_sum += m;
            c += m * Vector3::from(state.x[n]);
            p += m * Vector3::from(state.v[n]);
        }
        if m_sum <= 0.0 {
            continue;
        }
        c /= m_sum;
        let vc = p / m_sum;
        let (mut l, mut inertia) = (Vector3::zeros(), Matrix3::zeros());
        for n in nodes.clone() {
            let m = model.mass[n];
            let r = Vector3::from(state.x[n]) - c;
            l += m * r.cross(&(Vector3::from(state.v[n]) - vc));
            inertia += m * (Matrix3::identity() * r.dot(&r) - r * r.transpose());
        }
        let w = inertia
            .try_inverse()
            .map(|i| i * l)
            .unwrap_or_else(Vector3::zeros);
        for n in nodes {
            let r = Vector3::from(state.x[n]) - c;
            let dv = Vector3::from(state.v[n]) - vc - w.cross(&r);
            total += 0.5 * model.mass[n] * dv.norm_squared();
        }
    }
    total
}

fn speed_vs_error_plot(path: &Path, outcomes: &[CaseOutcome]) -> Result<()> {
    let mut names: Vec<&str> = outcomes.iter().map(|o| o.case.as_str()).collect();
    names.dedup();
    let series = names
        .iter()
        .map(|n| Series {
            label: n.to_string(),
            points: outcomes
                .iter()
                .filter(|o| o.case == *n)
                .map(|o| (o.wall_s, 100.0 * o.error.max(1e-6)))
                .collect(),
            theory: false,
        })
        .collect();
    plot::draw(
        path,
        &Plot {
            title: "speed vs error (all cases, all MR)",
            x_label: "wall time (s)",
            y_label: "error vs reference (%)",
            x_scale: Scale::Log,
            y_scale: Scale::Log,
            series,
        },
    )
    .map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))
}

/// Parses `--mr 0.09,0.045` and checks every value against each selected case's bound.
pub fn parse_mr_list(
    s: &str,
    cases: &[Box<dyn Case>],
) -> std::result::Result<Vec<f64>, InputError> {
    s.split(',')
        .map(|p| {
            let v: f64 = p.trim().parse().map_err(|_| {
                InputError::new("<command line>", "--mr", format!("'{p}' is not a number"))
            })?;
            match cases
                .iter()
                .find(|c| !(v.is_finite() && v > 0.0 && v < c.max_mr()))
            {
                None => Ok(v),
                Some(c) => Err(InputError::new(
                    "<command line>",
                    "--mr",
                    format!(
                        "meshing ratio of {} must be in (0, {}), got {v}",
                        c.name(),
                        c.max_mr()
                    ),
                )),
            }
        })
        .collect()
}
