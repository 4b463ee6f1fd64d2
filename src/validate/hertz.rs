//! Hertz normal contact: sphere squeezed between two rigid frictionless plates.
//!
//! Error metric: max |F − F_ref|/F_ref over the samples with F_ref in [0.5 N, 50 N], where
//! F_ref(δ) is the converged finite-sphere reference (THEORY.md §1); the distance from
//! half-space Hertz, max |F − F_H|/F_H over the same samples, is reported beside it.
//!
//! The reference is linear elastic; the solver's St Venant–Kirchhoff law is softer in
//! compression at the contact strains of this range (≈ −3.7 % in F at 50 N once the mesh
//! is converged), so the finest meshes do not converge to zero error: see
//! docs/BENCHMARKS.md (Validation).

use super::reference::{FiniteSphereReference, Hertz};
use super::runner::{case_solver, load_case_scene, Case, CaseOutcome, Probe};
use crate::error::{MufeError, Result};
use crate::io::plot::{Plot, Scale, Series};
use crate::material::ElasticParameters;
use crate::scene::ShapeSpec;
use serde_json::json;

pub const SCENE: &str = include_str!("../../jobs/validation/hertz.toml");

/// Force window of the error metric (N).
pub const FORCE_RANGE: (f64, f64) = (0.5, 50.0);

/// Accuracy target at the finest meshing ratio (fraction of F_ref).
pub const TARGET: f64 = 0.03;

/// Meshing ratio of the quick run (`--quick`, `cargo test`).
pub const QUICK_MR: f64 = 0.0023;

pub struct HertzCase;

impl HertzCase {
    fn material_and_radius(scene: &crate::scene::Scene) -> Result<(ElasticParameters, f64)> {
        let g = &scene.grains[0];
        let m = &scene.materials[&g.material];
        let ShapeSpec::Sphere(s) = &g.shape else {
            return Err(MufeError::Run("hertz: grain 0 must be a sphere".into()));
        };
        Ok((
            ElasticParameters {
                youngs_modulus: m.youngs_modulus,
                poisson_ratio: m.poisson_ratio,
                density: m.density,
            },
            s.radius,
        ))
    }
}

impl Case for HertzCase {
    fn name(&self) -> &'static str {
        "hertz"
    }

    fn default_mrs(&self, quick: bool) -> Vec<f64> {
        if quick {
            vec![QUICK_MR]
        } else {
            vec![0.0045, 0.0032, 0.0023, 0.0016]
        }
    }

    fn target(&self, quick: bool) -> f64 {
        if quick {
            super::QUICK_TOLERANCE_FACTOR * TARGET
        } else {
            TARGET
        }
    }

    fn run(&self, mr: f64, quick: bool, overrides: &[String]) -> Result<CaseOutcome> {
        let base = load_case_scene("hertz", SCENE, &[])?;
        let (material, radius) = Self::material_and_radius(&base.scene)?;
        let s = mr * 2.0 * radius;
        let mut sets = vec![
            format!("grains[0].shape.sphere.refine[0].seeding={s:e}"),
            format!("grains[0].shape.sphere.refine[1].seeding={s:e}"),
        ];
        sets.extend_from_slice(overrides);
        let loaded = load_case_scene("hertz", SCENE, &sets)?;
        let mut solver = case_solver(&loaded)?;
        let reference = FiniteSphereReference::load();
        let hertz = Hertz::sphere_on_flat(&material, radius);

        // first touch: the plates start at z_top ≥ R and z_bottom ≤ −R (a small gap lets them
        // reach their constant speed before touching); the faceted sphere's extreme nodes are
        // at z_max ≤ R, so δ = plate travel − (z_top − z_max).
        let wall_z = |name: &str| -> Result<f64> {
            loaded
                .scene
                .walls
                .iter()
                .find(|w| w.name == name)
                .map(|w| w.point[2])
                .ok_or_else(|| MufeError::Run(format!("hertz: no wall '{name}'")))
        };
        let z_max = solver
            .state
            .x
            .iter()
            .map(|p| p[2])
            .fold(f64::NEG_INFINITY, f64::max);
        let z_min = solver
            .state
            .x
            .iter()
            .map(|p| p[2])
            .fold(f64::INFINITY, f64::min);
        let (gap_top, gap_bottom) = (wall_z("top")? - z_max, z_min - wall_z("bottom")?);
        let delta_end = hertz.approach(1.04 * FORCE_RANGE.1 / 1.05);
        let mut probe = Probe::new(&solver);
        let sample_every =
            ((loaded.scene.output.history_interval.unwrap_or(5e-8) / solver.model.dt).round()
                as u64)
                .max(1);
        let max_steps = (loaded.scene.simulation.duration / solver.model.dt).ceil() as u64;
        let mut curve = Vec::new();
        let mut error_curve = Vec::new();
        let (mut err, mut err_hertz, mut ke_ie, mut pen_ratio): (f64, f64, f64, f64) =
            (0.0, 0.0, 0.0, 0.0);
        let mut in_range = 0;
        while solver.state.step < max_steps {
            solver.step()?;
            if solver.state.step % sample_every != 0 {
                continue;
            }
            probe.sample(&solver);
            let d_top = -probe.get("top_displacement_z")? - gap_top;
            let d_bottom = probe.get("bottom_displacement_z")? - gap_bottom;
            let delta = 0.5 * (d_top + d_bottom);
            if delta <= 0.0 {
                continue;
            }
            let force =
                0.5 * (probe.get("top_force_z")?.abs() + probe.get("bottom_force_z")?.abs());
            if let Some(f_ref) = reference.force(&material, radius, delta) {
                // plotted over the reference's range (below it a handful of nodes touch)
                curve.push((delta * 1e6, force));
                if f_ref >= FORCE_RANGE.0 && f_ref <= FORCE_RANGE.1 {
                    in_range += 1;
                    err = err.max((force - f_ref).abs() / f_ref);
                    error_curve.push((f_ref, 100.0 * (force - f_ref) / f_ref));
                    err_hertz =
                        err_hertz.max((force - hertz.force(delta)).abs() / hertz.force(delta));
                    let ie = probe.get("internal_energy")?;
                    ke_ie = ke_ie.max(probe.get("kinetic_energy")? / ie.max(1e-300));
                    pen_ratio = pen_ratio.max(probe.get("max_penetration").unwrap_or(0.0) / delta);
                }
            }
            if delta >= delta_end {
                break;
            }
        }
        if in_range < 5 {
            return Err(MufeError::Run(format!("hertz at MR {mr}: only {in_range} samples in the force window; lengthen simulation.duration")));
        }
        let target = self.target(quick);
        let mut details = serde_json::Map::new();
        details.insert("error_vs_half_space_hertz".into(), json!(err_hertz));
        details.insert("max_kinetic_over_internal".into(), json!(ke_ie));
        details.insert("max_penetration_over_delta".into(), json!(pen_ratio));
        details.insert("seeding_at_contact_m".into(), json!(s));
        details.insert("samples_in_window".into(), json!(in_range));
        details.insert(
            "added_mass_fraction".into(),
            json!(solver.model.added_mass / solver.model.total_physical_mass()),
        );
        Ok(CaseOutcome {
            case: "hertz".into(),
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
        ("reference force F_ref (N)", Scale::Log)
    }

    fn plot(&self, outcomes: &[CaseOutcome]) -> (Plot<'static>, Vec<Series>) {
        let base = load_case_scene("hertz", SCENE, &[]).ok();
        let (material, radius) = base
            .and_then(|b| Self::material_and_radius(&b.scene).ok())
            .unwrap_or((ElasticParameters::paper_glass(), 1.1e-3));
        let reference = FiniteSphereReference::load();
        let hertz = Hertz::sphere_on_flat(&material, radius);
        let d_max = outcomes
            .iter()
            .flat_map(|o| o.curve.iter().map(|p| p.0))
            .fold(8.0, f64::max)
            * 1e-6;
        let deltas: Vec<f64> = (0..200)
            .map(|i| 0.05e-6 * (d_max / 0.05e-6).powf(i as f64 / 199.0))
            .collect();
        let fin = Series {
            label: "finite-sphere reference (THEORY §1)".into(),
            points: deltas
                .iter()
                .filter_map(|&d| reference.force(&material, radius, d).map(|f| (d * 1e6, f)))
                .collect(),
            theory: true,
        };
        let half = Series {
            label: "half-space Hertz".into(),
            points: deltas.iter().map(|&d| (d * 1e6, hertz.force(d))).collect(),
            theory: true,
        };
        (
            Plot {
                title: "Hertz: sphere between rigid plates",
                x_label: "approach of each plate δ (µm)",
                y_label: "plate force F (N)",
                x_scale: Scale::Log,
                y_scale: Scale::Log,
                series: vec![],
            },
            vec![fin, half],
        )
    }
}
