//! The energy ledger over time, drawn as `DIR/energy.png` at the end of a run.

use crate::error::{MufeError, Result};

/// The energy ledger over time, drawn as `DIR/energy.png` at the end of a run.
#[derive(Default)]
pub struct EnergyPlot {
    /// (t, ALLKE, ALLIE, ALLWK, ALLFD, ALLVD, ETOTAL) per history row.
    rows: Vec<[f64; 7]>,
}

impl EnergyPlot {
    /// Takes the columns it needs from a history row (layout of [`history_columns`]).
    pub fn push(&mut self, row: &[f64]) {
        self.rows
            .push([row[0], row[2], row[5], row[8], row[7], row[9], row[10]]);
    }

    pub fn draw(&self, path: &std::path::Path) -> Result<()> {
        use crate::io::plot::{draw, energy_unit, Plot, Scale, Series};
        let names = [
            "kinetic ALLKE",
            "internal ALLIE",
            "external work ALLWK",
            "friction ALLFD",
            "damping ALLVD",
            "balance ETOTAL",
        ];
        let largest = self
            .rows
            .iter()
            .flat_map(|r| r[1..].iter().map(|v| v.abs()))
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        let (unit, per_joule) = energy_unit(largest);
        let series = names
            .iter()
            .enumerate()
            .map(|(k, name)| Series {
                label: (*name).into(),
                points: self
                    .rows
                    .iter()
                    .map(|r| (r[0] * 1e6, r[k + 1] * per_joule))
                    .collect(),
                theory: k == 5,
            })
            .collect();
        let y_label = format!("energy ({unit})");
        draw(
            path,
            &Plot {
                title: "energy ledger",
                x_label: "time (µs)",
                y_label: &y_label,
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series,
            },
        )
        .map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))
    }
}
