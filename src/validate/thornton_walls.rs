//! `mufe validate thornton_walls`: the peak stress ratio of a walled FCC cell in triaxial
//! compression against Thornton's σ1/σ3 = 2(1+μ)/(1−μ) (docs/THEORY.md §5, §9) for
//! μ = 0.22, 0.3, 0.4, 0.5, 0.6, rows `thornton_walls_mu<μ>`.
//!
//! Error = |peak σ1/σ3 − theory| / theory, σ on the lattice span between outer sphere
//! centres. Target at each μ: no further from theory than rigid-sphere DEM with free
//! rotations in the same walled 172-sphere block ([`DEM_SHORTFALL`]) plus one percentage
//! point, and ≤ 5 % at μ = 0.22. The walls let the boundary spheres roll, so the walled
//! cell fails below the infinite array; docs/THEORY.md §9 says how much.
//!
//! The cell ([`super::thornton_scene`]) runs through `mufe run`'s driver (stages, servo
//! walls, results.h5 per μ in `DIR/thornton_walls/mu_<μ>/`). Stage 1 (isotropic
//! compression) is run once, at the first μ, and kept as a checkpoint; every other μ
//! branches from it (`--restart … --branch`) and runs stage 2 only. Under isotropic
//! stress no contact of a perfect FCC array carries tangential force, so the
//! consolidated state does not depend on μ; each row records the sliding contacts at the
//! end of stage 1 so that this is checked, not assumed.

use super::record::Recorder;
use super::runner::{load_case_scene, Case, CaseOutcome};
use super::scenes::Params;
use super::thornton_scene::{thornton_walls_scene, ThorntonInputs, ThorntonParams};
use crate::driver::RunOptions;
use crate::error::{MufeError, Result};
use crate::io::plot::{self, Plot, Scale, Series};
use crate::scene::parse_scene;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The friction sweep.
pub const FRICTIONS: [f64; 5] = [0.22, 0.3, 0.4, 0.5, 0.6];
/// Rigid-sphere DEM with free rotations, 172 spheres (closed 3×3×3-cell block) between six
/// frictionless walls: relative shortfall of the peak ratio below Thornton at each μ of
/// [`FRICTIONS`] (docs/THEORY.md §9).
pub const DEM_SHORTFALL: [f64; 5] = [0.033, 0.047, 0.074, 0.114, 0.185];
/// The block the DEM baseline was measured on (cubic cells per side).
pub const DEM_CELLS: usize = 3;
/// Allowance beyond the DEM baseline (fraction of theory).
pub const DEM_ALLOWANCE: f64 = 0.01;
/// Upper bound of the error at the first μ (0.22).
pub const FIRST_TARGET: f64 = 0.05;

/// Thornton's peak σ1/σ3 of an FCC array loaded along a cube axis.
pub fn thornton_ratio(mu: f64) -> f64 {
    2.0 * (1.0 + mu) / (1.0 - mu)
}

/// The target of the row of `FRICTIONS[i]` (module docs).
pub fn target_at(i: usize) -> f64 {
    let dem = DEM_SHORTFALL[i] + DEM_ALLOWANCE;
    if i == 0 {
        dem.min(FIRST_TARGET)
    } else {
        dem
    }
}

pub struct ThorntonWallsCase;

const NAME: &str = "thornton_walls";

impl ThorntonWallsCase {
    /// Runs the cell at `FRICTIONS[i]`, from t = 0 or branching from a stage-1 checkpoint.
    /// Returns the outcome and the stage-1 checkpoint to branch the next μ from.
    fn run_friction(
        &self,
        i: usize,
        mr: f64,
        overrides: &[String],
        params: &Params,
        record: &Recorder,
        branch_from: Option<&Path>,
    ) -> Result<(CaseOutcome, PathBuf)> {
        let mu = FRICTIONS[i];
        let base = load_case_scene(NAME, self.shipped_scene(), overrides)?;
        let inputs = ThorntonInputs::from_scene(&base)?;
        let mut p = params.thornton_walls.clone();
        p.contact_seeding = 2.0 * mr;
        let text = thornton_walls_scene(&inputs, mu, &p);
        // the sweep sets the friction; every other override still wins
        let kept: Vec<String> = overrides
            .iter()
            .filter(|o| !o.trim_start().starts_with("contact.friction"))
            .cloned()
            .collect();
        let loaded = parse_scene(
            &format!("{} (as generated, μ = {mu})", inputs.file),
            &text,
            &kept,
        )?;
        let out = record.root.join(NAME).join(format!("mu_{mu:.2}"));
        let t0 = Instant::now();
        let summary = crate::driver::run(
            record.domain,
            &loaded,
            &RunOptions {
                out: out.clone(),
                threads: rayon::current_num_threads(),
                max_steps: None,
                quiet: true,
                force: false,
                checkpoint_every: None,
                restart: branch_from.map(Path::to_path_buf),
                branch: branch_from.is_some(),
            },
        )?;
        let wall_s = t0.elapsed().as_secs_f64();
        let stage_file = match branch_from {
            Some(f) => f.to_path_buf(),
            None => crate::io::checkpoint::stage_checkpoint_path(&out, 1, "isotropic"),
        };
        let h = History::read(&summary.results)?;
        let theory = thornton_ratio(mu);
        let shear: Vec<usize> = (0..h.time.len()).filter(|&k| h.stage[k] >= 2.0).collect();
        let peak_row = shear
            .iter()
            .copied()
            .max_by(|&a, &b| h.ratio[a].total_cmp(&h.ratio[b]))
            .ok_or_else(|| MufeError::Run(format!("{NAME}: μ = {mu}: no stage-2 rows")))?;
        let peak = h.ratio[peak_row];
        let start = shear[0];
        let strain = |k: usize| h.strain_z[k] - h.strain_z[start];
        let error = (peak - theory).abs() / theory;
        let target = target_at(i);
        let dem_applies = p.cell_count() == DEM_CELLS;
        let dem = theory * (1.0 - DEM_SHORTFALL[i]);
        let max_ke_ie = shear
            .iter()
            .map(|&k| h.kinetic[k] / h.internal[k].max(f64::MIN_POSITIVE))
            .fold(0.0f64, f64::max);
        let stage1_sliding = if start > 0 { h.sliding[start - 1] } else { 0.0 };
        let mut details = serde_json::Map::new();
        details.insert("friction".into(), json!(mu));
        details.insert("theory_ratio".into(), json!(theory));
        details.insert("peak_ratio".into(), json!(peak));
        details.insert("peak_axial_strain".into(), json!(strain(peak_row)));
        details.insert("peak_time_s".into(), json!(h.time[peak_row]));
        details.insert(
            "dem_baseline_ratio".into(),
            if dem_applies { json!(dem) } else { json!(null) },
        );
        details.insert("dem_shortfall".into(), json!(DEM_SHORTFALL[i]));
        details.insert(
            "mean_grain_rotation_at_peak_rad".into(),
            json!(h.rotation[peak_row]),
        );
        details.insert(
            "sliding_contacts_at_peak".into(),
            json!(h.sliding[peak_row]),
        );
        details.insert("contacts_at_peak".into(), json!(h.contacts[peak_row]));
        details.insert("max_kinetic_over_internal_stage2".into(), json!(max_ke_ie));
        details.insert(
            "kinetic_over_internal_at_peak".into(),
            json!(h.kinetic[peak_row] / h.internal[peak_row].max(f64::MIN_POSITIVE)),
        );
        details.insert(
            "lateral_stress_at_peak_pa".into(),
            json!(h.lateral[peak_row]),
        );
        details.insert(
            "stage1_sliding_contacts_at_end".into(),
            json!(stage1_sliding),
        );
        details.insert(
            "branched_from".into(),
            json!(branch_from.map(|f| f.display().to_string())),
        );
        details.insert("energy_balance_error".into(), json!(h.balance_error()));
        details.insert(
            "results".into(),
            json!(summary.results.display().to_string()),
        );
        details.insert("wall_s_run".into(), json!(wall_s));
        details.insert(
            "scene".into(),
            json!({
                "file": inputs.file,
                "youngs_modulus_pa": inputs.material.youngs_modulus,
                "poisson_ratio": inputs.material.poisson_ratio,
                "density_kg_m3": inputs.material.density,
                "radius_m": inputs.radius,
                "friction": mu,
                "confining_stress_pa": inputs.confining_stress,
                "cells": p.cell_count(),
                "inertial_number": p.inertial_number,
            }),
        );
        let curve = shear.iter().map(|&k| (strain(k), h.ratio[k])).collect();
        let outcome = CaseOutcome {
            case: format!("{NAME}_mu{mu}"),
            mr,
            elements: summary.elements,
            steps: summary.steps_run,
            wall_s,
            error,
            target,
            pass: error <= target,
            details,
            curve,
            error_curve: Vec::new(),
        };
        if record.domain.is_root() {
            println!(
                "  μ = {mu}: peak σ1/σ3 = {peak:.4} at axial strain {:.3e}; Thornton {theory:.4}, rigid DEM (walls, free rotations) {}; mean grain rotation at the peak {:.2e} rad; lateral σ at the peak {:.4e} Pa; ALLKE/ALLIE {:.1e} at the peak, {max_ke_ie:.1e} at most; {} sliding contacts at the end of stage 1",
                strain(peak_row),
                if dem_applies { format!("{dem:.4}") } else { format!("n/a for {} cells", p.cell_count()) },
                h.rotation[peak_row],
                h.lateral[peak_row],
                h.kinetic[peak_row] / h.internal[peak_row].max(f64::MIN_POSITIVE),
                stage1_sliding
            );
        }
        Ok((outcome, stage_file))
    }
}

impl Case for ThorntonWallsCase {
    fn name(&self) -> &'static str {
        NAME
    }
    fn shipped_scene(&self) -> &'static str {
        include_str!("../../jobs/validation/thornton_walls.toml")
    }
    /// The contact meshing ratio (contact seeding / 2R) of the cell; the sweep is over μ.
    fn sweep_mrs(&self) -> Vec<f64> {
        vec![0.5 * ThorntonParams::default().contact_seeding]
    }
    fn quick_mr(&self) -> f64 {
        0.5 * ThorntonParams::default().contact_seeding
    }
    fn full_target(&self) -> f64 {
        target_at(0)
    }
    fn target(&self, _quick: bool) -> f64 {
        target_at(0)
    }
    /// One run at the first μ (0.22), from t = 0.
    fn run(
        &self,
        mr: f64,
        _quick: bool,
        overrides: &[String],
        params: &Params,
        record: Option<&Recorder>,
    ) -> Result<CaseOutcome> {
        let record = record.ok_or_else(|| {
            MufeError::Run(format!(
                "{NAME} runs through the driver and needs an output directory"
            ))
        })?;
        Ok(self.run_friction(0, mr, overrides, params, record, None)?.0)
    }
    /// μ = 0.22 from t = 0; with `quick` only that; otherwise every other μ branched from
    /// its stage-1 checkpoint.
    fn run_sweep(
        &self,
        mrs: &[f64],
        quick: bool,
        overrides: &[String],
        params: &Params,
        record: Option<&Recorder>,
        report: &mut dyn FnMut(&mut CaseOutcome),
    ) -> Result<Vec<CaseOutcome>> {
        let record = record.ok_or_else(|| {
            MufeError::Run(format!(
                "{NAME} runs through the driver and needs an output directory"
            ))
        })?;
        let count = if quick { 1 } else { FRICTIONS.len() };
        let mut outcomes = Vec::new();
        for &mr in mrs {
            let mut stage1: Option<PathBuf> = None;
            for i in 0..count {
                let (mut o, kept) =
                    self.run_friction(i, mr, overrides, params, record, stage1.as_deref())?;
                stage1 = Some(kept);
                report(&mut o);
                outcomes.push(o);
            }
        }
        Ok(outcomes)
    }
    /// The cell at the first μ (`--write-scenes`).
    fn generated_scene(&self, overrides: &[String], params: &Params) -> Result<String> {
        let base = load_case_scene(NAME, self.shipped_scene(), overrides)?;
        let inputs = ThorntonInputs::from_scene(&base)?;
        Ok(thornton_walls_scene(
            &inputs,
            FRICTIONS[0],
            &params.thornton_walls,
        ))
    }
    fn plot(&self, outcomes: &[CaseOutcome]) -> (Plot<'static>, Vec<Series>) {
        let theory: Vec<(f64, f64)> = (0..=40)
            .map(|k| {
                let mu = 0.2 + 0.01 * k as f64;
                (mu, thornton_ratio(mu))
            })
            .collect();
        let dem: Vec<(f64, f64)> = FRICTIONS
            .iter()
            .zip(DEM_SHORTFALL)
            .map(|(&mu, s)| (mu, thornton_ratio(mu) * (1.0 - s)))
            .collect();
        let fe: Vec<(f64, f64)> = outcomes
            .iter()
            .filter_map(|o| {
                Some((
                    o.details.get("friction")?.as_f64()?,
                    o.details.get("peak_ratio")?.as_f64()?,
                ))
            })
            .collect();
        let elements = outcomes.first().map_or(0, |o| o.elements);
        (
            Plot {
                title: "walled FCC cell: peak stress ratio vs friction",
                x_label: "friction coefficient μ",
                y_label: "peak σ1/σ3",
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series: Vec::new(),
            },
            vec![
                Series {
                    label: "Thornton 2(1+μ)/(1−μ)".into(),
                    points: theory,
                    theory: true,
                },
                Series {
                    label: "rigid-sphere DEM, 172 spheres, walls, free rotations".into(),
                    points: dem,
                    theory: true,
                },
                Series {
                    label: format!("μFE ({elements} elements)"),
                    points: fe,
                    theory: false,
                },
            ],
        )
    }
    /// `thornton_walls.png` (peak ratio vs μ over theory and the DEM baseline, the paper's
    /// Fig. 7b) and `thornton_walls_curves.png` (σ1/σ3 vs axial strain, Fig. 7a).
    fn draw_plots(&self, outcomes: &[CaseOutcome], out: &Path) -> Result<()> {
        let (mut p, series) = self.plot(outcomes);
        p.series = series;
        let png = out.join(format!("{NAME}.png"));
        plot::draw(&png, &p).map_err(|e| MufeError::Io(format!("{}: {e}", png.display())))?;
        let mut curves: Vec<Series> = Vec::new();
        for o in outcomes {
            let mu = o
                .details
                .get("friction")
                .and_then(|v| v.as_f64())
                .unwrap_or(0.0);
            let end = o.curve.last().map_or(0.0, |c| c.0);
            curves.push(Series {
                label: if curves.is_empty() {
                    "Thornton".into()
                } else {
                    String::new()
                },
                points: vec![(0.0, thornton_ratio(mu)), (end, thornton_ratio(mu))],
                theory: true,
            });
            curves.push(Series {
                label: format!("μ = {mu}"),
                points: o.curve.clone(),
                theory: false,
            });
        }
        let png = out.join(format!("{NAME}_curves.png"));
        plot::draw(
            &png,
            &Plot {
                title: "walled FCC cell: stress ratio vs axial strain (stage 2)",
                x_label: "axial strain (–)",
                y_label: "σ1/σ3 (lattice-span areas)",
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series: curves,
            },
        )
        .map_err(|e| MufeError::Io(format!("{}: {e}", png.display())))
    }
}

/// The `/history` columns the case reads from a run's results.h5.
struct History {
    time: Vec<f64>,
    stage: Vec<f64>,
    ratio: Vec<f64>,
    strain_z: Vec<f64>,
    rotation: Vec<f64>,
    sliding: Vec<f64>,
    contacts: Vec<f64>,
    kinetic: Vec<f64>,
    internal: Vec<f64>,
    /// Mean of σx and σy (Pa).
    lateral: Vec<f64>,
    balance: Vec<f64>,
    terms: Vec<Vec<f64>>,
}

impl History {
    fn read(path: &Path) -> Result<Self> {
        let io = |e: hdf5::Error| MufeError::Io(format!("{}: {e}", path.display()));
        let file = hdf5::File::open(path).map_err(io)?;
        let column = |name: &str| -> Result<Vec<f64>> {
            file.dataset(&format!("history/{name}"))
                .and_then(|d| d.read_raw::<f64>())
                .map_err(io)
        };
        let terms = [
            "internal_energy",
            "kinetic_energy",
            "external_work",
            "friction_dissipation",
            "damping_dissipation",
            "contact_energy",
        ]
        .iter()
        .map(|n| column(n))
        .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            time: column("time")?,
            stage: column("stage")?,
            ratio: column("stress_ratio")?,
            strain_z: column("strain_z")?,
            rotation: column("mean_grain_rotation")?,
            sliding: column("sliding_grain_pair_contacts")?,
            contacts: column("grain_pair_contacts")?,
            kinetic: column("kinetic_energy")?,
            internal: column("internal_energy")?,
            lateral: column("sigma_x")?
                .iter()
                .zip(column("sigma_y")?)
                .map(|(x, y)| 0.5 * (x + y))
                .collect(),
            balance: column("energy_balance")?,
            terms,
        })
    }

    /// Largest |energy_balance| over the largest energy term (the validation convention).
    fn balance_error(&self) -> f64 {
        let scale = self
            .terms
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = self.balance.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if scale > 0.0 {
            worst / scale
        } else {
            worst
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;

    #[test]
    fn shipped_scene_is_the_generator_output_for_glass_at_50_kpa() {
        let case = ThorntonWallsCase;
        let loaded = parse_scene(NAME, case.shipped_scene(), &[]).unwrap();
        let inputs = ThorntonInputs::from_scene(&loaded).unwrap();
        assert_eq!(inputs.radius, 1.1e-3);
        assert_eq!(inputs.confining_stress, 5.0e4);
        assert_eq!(inputs.material.youngs_modulus, 63e9);
        let generated = case.generated_scene(&[], &Params::default()).unwrap();
        assert!(
            generated == case.shipped_scene(),
            "jobs/validation/thornton_walls.toml differs from the generator's output: rewrite \
             it with `mufe validate thornton_walls --write-scenes jobs/validation`"
        );
    }

    #[test]
    fn another_material_and_size_gives_the_same_cell_in_its_own_units() {
        let case = ThorntonWallsCase;
        let sets: Vec<String> = [
            "materials.glass.youngs_modulus=2.1e11",
            "materials.glass.poisson_ratio=0.3",
            "materials.glass.density=7850",
            "packings[0].sphere.radius=2.5e-3",
            "stages[0].walls.top.servo.stress=2.0e5",
        ]
        .map(String::from)
        .to_vec();
        let text = case.generated_scene(&sets, &Params::default()).unwrap();
        let steel = parse_scene("steel", &text, &[]).unwrap();
        let inputs = ThorntonInputs::from_scene(&steel).unwrap();
        assert_eq!(inputs.radius, 2.5e-3);
        assert_eq!(inputs.confining_stress, 2.0e5);
        // the top wall touches the outer spheres: 3 cells of a = 2√2 R plus R
        let top = steel.scene.walls.iter().find(|w| w.name == "top").unwrap();
        let expected = 3.0 * 2.0 * std::f64::consts::SQRT_2 * 2.5e-3 + 2.5e-3;
        assert!((top.point[2] - expected).abs() < 1e-12, "{}", top.point[2]);
        // the step is the same fraction of R/c_p as for the glass
        let unit = |l: &crate::scene::LoadedScene, r: f64| {
            let m = &l.scene.materials["glass"];
            let p = crate::material::ElasticParameters {
                youngs_modulus: m.youngs_modulus,
                poisson_ratio: m.poisson_ratio,
                density: m.density,
            };
            l.scene.simulation.target_dt.unwrap() / (r / p.dilatational_wave_speed())
        };
        let glass = parse_scene(NAME, case.shipped_scene(), &[]).unwrap();
        let (a, b) = (unit(&glass, 1.1e-3), unit(&steel, 2.5e-3));
        assert!((a / b - 1.0).abs() < 1e-9, "{a} vs {b}");
    }

    #[test]
    fn targets_are_the_dem_baseline_plus_a_point_and_5_percent_at_the_first_friction() {
        assert!((target_at(0) - 0.043).abs() < 1e-15);
        for i in 1..FRICTIONS.len() {
            assert!((target_at(i) - DEM_SHORTFALL[i] - 0.01).abs() < 1e-15);
        }
        assert!((thornton_ratio(0.22) - 2.0 * 1.22 / 0.78).abs() < 1e-15);
    }
}
