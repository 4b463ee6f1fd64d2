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
        use crate::io::plot::{draw, Plot, Scale, Series};
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

/// The SI prefix that shows energies up to `largest` (J) as numbers between 1 and 1000:
/// (unit, multiplier from joules).
fn energy_unit(largest: f64) -> (&'static str, f64) {
    const UNITS: [(&str, f64); 6] = [
        ("J", 1.0),
        ("mJ", 1e3),
        ("µJ", 1e6),
        ("nJ", 1e9),
        ("pJ", 1e12),
        ("fJ", 1e15),
    ];
    UNITS
        .iter()
        .copied()
        .find(|&(_, k)| largest * k >= 1.0)
        .unwrap_or(UNITS[UNITS.len() - 1])
}

#[cfg(test)]
mod tests {
    use super::energy_unit;

    #[test]
    fn energies_are_shown_between_one_and_a_thousand() {
        assert_eq!(energy_unit(2.5).0, "J");
        assert_eq!(energy_unit(0.7).0, "mJ");
        assert_eq!(energy_unit(3.2e-6).0, "µJ");
        assert_eq!(energy_unit(4.0e-10).0, "pJ");
        assert_eq!(energy_unit(0.0).0, "fJ");
    }
}
