//! `DIR/stress_ratio.png` of a staged run in a box of walls: the stress ratio σ1/σ3 (on
//! the lattice-span areas) against the axial strain during the stages that strain the
//! specimen, over Thornton's failure ratio 2(1+μ)/(1−μ) for the scene's friction and the
//! frictionless FCC bound 2 (docs/THEORY.md §7).

use crate::error::{MufeError, Result};
use crate::io::plot::{draw, Plot, Scale, Series};
use crate::io::results::HistoryColumn;
use crate::solver::Solver;

pub struct TriaxialPlot {
    /// Positions of `stress_ratio`, the axial `strain_*` and `stage` in a history row.
    ratio: usize,
    strain: usize,
    stage: usize,
    /// Stages (1-based, as in the `stage` column) that strain the specimen.
    straining: Vec<f64>,
    friction: f64,
    /// (axial strain, ratio) per history row of those stages.
    points: Vec<(f64, f64)>,
}

impl TriaxialPlot {
    /// `None` unless the run is staged, measures a cell and strains it in some stage.
    pub fn new(solver: &Solver, columns: &[HistoryColumn]) -> Option<Self> {
        let plan = solver.model.stages.as_ref().filter(|p| p.staged)?;
        plan.cell.as_ref()?;
        let straining: Vec<f64> = (plan.stages.iter().enumerate())
            .filter(|(_, s)| s.strains)
            .map(|(i, _)| (i + 1) as f64)
            .collect();
        if straining.is_empty() {
            return None;
        }
        let at = |name: &str| columns.iter().position(|c| c.name == name);
        Some(Self {
            ratio: at("stress_ratio")?,
            strain: at(&format!("strain_{}", ["x", "y", "z"][plan.axial]))?,
            stage: at("stage")?,
            straining,
            friction: solver.model.contact.friction,
            points: Vec::new(),
        })
    }

    /// Takes its point from a reduced history row.
    pub fn push(&mut self, row: &[f64]) {
        if self.straining.contains(&row[self.stage]) {
            self.points.push((1e3 * row[self.strain], row[self.ratio]));
        }
    }

    pub fn draw(&self, path: &std::path::Path) -> Result<()> {
        if self.points.is_empty() {
            return Ok(());
        }
        let series = self.series();
        draw(
            path,
            &Plot {
                title: "stress ratio during axial loading (docs/THEORY.md §7)",
                x_label: "axial strain since t = 0 (‰)",
                y_label: "σ1/σ3 (–)",
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series,
            },
        )
        .map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))
    }

    /// The two theory lines across the strains of the points (a strain range of its own
    /// around a single point, so that the lines are seen), then the points.
    fn series(&self) -> Vec<Series> {
        let strains = self.points.iter().map(|p| p.0);
        let lo = strains.clone().fold(f64::INFINITY, f64::min);
        let hi = strains.fold(f64::NEG_INFINITY, f64::max);
        // ‰: half the strain itself, at least 10⁻³ ‰, either side of a lone point
        let pad = if hi > lo {
            0.0
        } else {
            0.5 * lo.abs().max(1e-3)
        };
        let (lo, hi) = (lo - pad, hi + pad);
        let mu = self.friction;
        let thornton = 2.0 * (1.0 + mu) / (1.0 - mu);
        let line = |label: String, y: f64| Series {
            label,
            points: vec![(lo, y), (hi, y)],
            theory: true,
        };
        vec![
            line(
                format!("Thornton 2(1+μ)/(1−μ) = {thornton:.3} (μ = {mu})"),
                thornton,
            ),
            line("frictionless FCC: 2".into(), 2.0),
            Series {
                label: "mufe: σ1/σ3 on the lattice span".into(),
                points: self.points.clone(),
                theory: false,
            },
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plot(points: Vec<(f64, f64)>) -> TriaxialPlot {
        TriaxialPlot {
            ratio: 0,
            strain: 1,
            stage: 2,
            straining: vec![2.0],
            friction: 0.3,
            points,
        }
    }

    #[test]
    fn theory_lines_span_the_points_and_a_lone_point_gets_a_range() {
        let spans = |p: &TriaxialPlot| -> Vec<(f64, f64)> {
            (p.series().iter().filter(|s| s.theory))
                .map(|s| (s.points[0].0, s.points[1].0))
                .collect()
        };
        let two = plot(vec![(0.1, 1.0), (0.4, 3.0)]);
        assert_eq!(spans(&two), vec![(0.1, 0.4); 2]);
        let thornton = two.series()[0].points[0].1;
        assert!((thornton - 2.0 * 1.3 / 0.7).abs() < 1e-12);
        for at in [0.0, 0.2, -0.05] {
            for (lo, hi) in spans(&plot(vec![(at, 1.5)])) {
                assert!(lo < at && at < hi && hi - lo >= 1e-3, "{at}: {lo} {hi}");
            }
        }
    }
}
