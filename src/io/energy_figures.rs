//! `mufe plot RUN/results.h5 [MORE.h5 …]`: the energy study figures of one run or of runs
//! side by side (an elastic and an elastic–plastic cell, or one cell at several contact
//! resolutions), read from `/history`:
//!
//! - `external_work.png`: ALLWK against time (the paper's Fig. 8);
//! - `strain_energy.png`: the grains' stress work ALLSE + ALLPD and its recoverable part
//!   ALLSE (Fig. 9a: equal for elastic grains);
//! - `dissipation.png`: plastic ALLPD and frictional ALLFD dissipation (Fig. 9b);
//! - `dissipation_indices.png`: plastic index ALLPD/(ALLSE + ALLPD) and friction index
//!   ALLFD/(ALLFD + ALLPD + ALLSE) (Fig. 11);
//!
//! and a table of the ledger at the peak stress ratio (when the run measured a cell) and
//! at the end. docs/RESULTS.md defines the columns.

use crate::error::{InputError, MufeError, Result};
use crate::io::plot::{draw, energy_unit, Plot, Scale, Series};
use std::path::{Path, PathBuf};

/// The `/history` series of one run that the energy figures use.
pub struct RunHistory {
    pub label: String,
    /// s.
    pub time: Vec<f64>,
    /// J: ALLWK, ALLKE, ALLSE, ALLPD, ALLFD, ALLVD, ETOTAL.
    pub external_work: Vec<f64>,
    pub kinetic: Vec<f64>,
    pub recoverable: Vec<f64>,
    pub plastic: Vec<f64>,
    pub friction: Vec<f64>,
    pub damping: Vec<f64>,
    pub balance: Vec<f64>,
    /// σ1/σ3 on the lattice span, when the run measured a cell.
    pub stress_ratio: Option<Vec<f64>>,
}

/// Ledger values of one history row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LedgerRow {
    pub time: f64,
    pub external_work: f64,
    pub kinetic: f64,
    pub recoverable: f64,
    pub plastic: f64,
    pub friction: f64,
    pub damping: f64,
    pub balance: f64,
}

impl LedgerRow {
    /// ALLPD / (ALLSE + ALLPD): the share of the grains' stress work that is plastic.
    pub fn plastic_index(&self) -> f64 {
        ratio(self.plastic, self.recoverable + self.plastic)
    }

    /// ALLFD / (ALLFD + ALLPD + ALLSE).
    pub fn friction_index(&self) -> f64 {
        ratio(
            self.friction,
            self.friction + self.plastic + self.recoverable,
        )
    }
}

fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else {
        0.0
    }
}

impl RunHistory {
    /// Reads a results file; a missing file or column is an input error naming both.
    pub fn read(path: &Path, label: &str) -> Result<Self> {
        let file_name = path.display().to_string();
        let bad = |item: &str, why: String| {
            MufeError::Input(InputError::new(file_name.clone(), item, why))
        };
        if !path.is_file() {
            return Err(bad("<file>", "no such file".into()));
        }
        let file = hdf5::File::open(path)
            .map_err(|e| bad("<file>", format!("not an HDF5 results file ({e})")))?;
        let column = |name: &str| -> Result<Vec<f64>> {
            let item = format!("/history/{name}");
            let ds = file
                .dataset(&format!("history/{name}"))
                .map_err(|_| bad(&item, "missing (not a mufe results file?)".into()))?;
            ds.read_raw::<f64>()
                .map_err(|e| bad(&item, format!("unreadable: {e}")))
        };
        let time = column("time")?;
        if time.is_empty() {
            return Err(bad(
                "/history/time",
                "no rows: the run wrote no history".into(),
            ));
        }
        // a job killed while it flushed its history can leave columns of other lengths
        let rows = time.len();
        let row_column = |name: &str| -> Result<Vec<f64>> {
            let values = column(name)?;
            if values.len() != rows {
                return Err(bad(
                    &format!("/history/{name}"),
                    format!("has {} rows where /history/time has {rows}", values.len()),
                ));
            }
            Ok(values)
        };
        let stress_ratio = if file.dataset("history/stress_ratio").is_ok() {
            Some(row_column("stress_ratio")?)
        } else {
            None
        };
        Ok(Self {
            label: label.to_string(),
            time,
            external_work: row_column("external_work")?,
            kinetic: row_column("kinetic_energy")?,
            recoverable: row_column("recoverable_strain_energy")?,
            plastic: row_column("plastic_dissipation")?,
            friction: row_column("friction_dissipation")?,
            damping: row_column("damping_dissipation")?,
            balance: row_column("energy_balance")?,
            stress_ratio,
        })
    }

    pub fn row(&self, i: usize) -> LedgerRow {
        LedgerRow {
            time: self.time[i],
            external_work: self.external_work[i],
            kinetic: self.kinetic[i],
            recoverable: self.recoverable[i],
            plastic: self.plastic[i],
            friction: self.friction[i],
            damping: self.damping[i],
            balance: self.balance[i],
        }
    }

    pub fn last(&self) -> LedgerRow {
        self.row(self.time.len() - 1)
    }

    /// The row of the largest stress ratio (the first of equal ones), if a cell was measured.
    pub fn peak(&self) -> Option<(f64, LedgerRow)> {
        let ratio = self.stress_ratio.as_ref()?;
        let (i, r) = ratio
            .iter()
            .enumerate()
            .filter(|(_, r)| r.is_finite())
            .fold(None, |best: Option<(usize, f64)>, (i, &r)| match best {
                Some((_, b)) if b >= r => best,
                _ => Some((i, r)),
            })?;
        Some((r, self.row(i)))
    }
}

/// A label for a results file: the name of its directory (`out/energy_plastic/results.h5`
/// → `energy_plastic`), or the file stem.
pub fn default_label(path: &Path) -> String {
    let dir = path
        .parent()
        .and_then(|p| p.file_name())
        .map(|s| s.to_string_lossy().into_owned());
    dir.filter(|d| !d.is_empty() && d != ".")
        .unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "run".into())
        })
}

/// Draws the four figures into `out` and returns their paths.
pub fn draw_energy_figures(runs: &[RunHistory], out: &Path) -> Result<Vec<PathBuf>> {
    let largest = runs
        .iter()
        .flat_map(|r| {
            (r.external_work.iter())
                .chain(&r.recoverable)
                .chain(&r.plastic)
                .chain(&r.friction)
        })
        .map(|v| v.abs())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let (unit, per_joule) = energy_unit(largest);
    let y_energy = format!("energy ({unit})");
    let curve = |run: &RunHistory, what: &str, values: &dyn Fn(usize) -> f64| Series {
        label: if runs.len() > 1 {
            format!("{}: {what}", run.label)
        } else {
            what.to_string()
        },
        points: (0..run.time.len())
            .map(|i| (run.time[i] * 1e3, values(i)))
            .collect(),
        theory: false,
    };
    let figures: [(&str, &str, &str, Vec<Series>); 4] = [
        (
            "external_work.png",
            "external work (Fig. 8 of the paper)",
            &y_energy,
            runs.iter()
                .map(|r| curve(r, "ALLWK", &|i| r.external_work[i] * per_joule))
                .collect(),
        ),
        (
            "strain_energy.png",
            "grains' strain energy: total ALLSE + ALLPD and recoverable ALLSE (Fig. 9a)",
            &y_energy,
            runs.iter()
                .flat_map(|r| {
                    [
                        curve(r, "ALLSE + ALLPD", &|i| {
                            (r.recoverable[i] + r.plastic[i]) * per_joule
                        }),
                        curve(r, "recoverable ALLSE", &|i| r.recoverable[i] * per_joule),
                    ]
                })
                .collect(),
        ),
        (
            "dissipation.png",
            "plastic ALLPD and frictional ALLFD dissipation (Fig. 9b)",
            &y_energy,
            runs.iter()
                .flat_map(|r| {
                    [
                        curve(r, "plastic ALLPD", &|i| r.plastic[i] * per_joule),
                        curve(r, "friction ALLFD", &|i| r.friction[i] * per_joule),
                    ]
                })
                .collect(),
        ),
        (
            "dissipation_indices.png",
            "plastic index ALLPD/(ALLSE+ALLPD), friction index ALLFD/(ALLFD+ALLPD+ALLSE) (Fig. 11)",
            "index (–)",
            runs.iter()
                .flat_map(|r| {
                    [
                        curve(r, "plastic index", &|i| r.row(i).plastic_index()),
                        curve(r, "friction index", &|i| r.row(i).friction_index()),
                    ]
                })
                .collect(),
        ),
    ];
    std::fs::create_dir_all(out).map_err(|e| MufeError::Io(format!("{}: {e}", out.display())))?;
    let mut written = Vec::new();
    for (name, title, y_label, series) in figures {
        let path = out.join(name);
        draw(
            &path,
            &Plot {
                title,
                x_label: "time (ms)",
                y_label,
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series,
            },
        )
        .map_err(|e| MufeError::Io(format!("{}: {e}", path.display())))?;
        written.push(path);
    }
    Ok(written)
}

/// The ledger at the peak stress ratio and at the end of each run, as a Markdown table
/// (energies in the unit of the largest external work, so small dissipations keep digits).
pub fn ledger_table(runs: &[RunHistory]) -> String {
    let largest = runs
        .iter()
        .flat_map(|r| r.external_work.iter())
        .fold(0.0_f64, |m, w| m.max(w.abs()));
    let (unit, per_joule) = energy_unit(largest);
    let mut s = format!(
        "| run | at | t (ms) | σ1/σ3 | ALLWK ({unit}) | ALLSE ({unit}) | ALLPD ({unit}) | \
         ALLFD ({unit}) | ALLVD ({unit}) | ALLKE ({unit}) | ALLPD/ALLFD | \
         recoverable ALLSE/(ALLSE+ALLPD) | friction index | balance/ALLWK |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for run in runs {
        let peak = run.peak();
        let rows = peak
            .map(|(r, row)| ("peak", Some(r), row))
            .into_iter()
            .chain([("end", None, run.last())]);
        for (at, ratio_value, row) in rows {
            let uj = |v: f64| format!("{:.4}", v * per_joule);
            s.push_str(&format!(
                "| {} | {at} | {:.4} | {} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {:.3} | {:.1e} |\n",
                run.label,
                row.time * 1e3,
                ratio_value.map_or("–".into(), |r| format!("{r:.4}")),
                uj(row.external_work),
                uj(row.recoverable),
                uj(row.plastic),
                uj(row.friction),
                uj(row.damping),
                uj(row.kinetic),
                if row.friction > 0.0 {
                    format!("{:.3}", row.plastic / row.friction)
                } else {
                    "–".into()
                },
                1.0 - row.plastic_index(),
                row.friction_index(),
                ratio(row.balance.abs(), row.external_work.abs()),
            ));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(label: &str, ratio: Option<Vec<f64>>) -> RunHistory {
        let n = 5;
        let ramp = |k: f64| (0..n).map(|i| k * i as f64).collect::<Vec<_>>();
        RunHistory {
            label: label.into(),
            time: ramp(1e-4),
            external_work: ramp(4e-6),
            kinetic: ramp(1e-9),
            recoverable: ramp(1e-6),
            plastic: ramp(2e-6),
            friction: ramp(1e-6),
            damping: vec![0.0; n],
            balance: vec![0.0; n],
            stress_ratio: ratio,
        }
    }

    #[test]
    fn indices_follow_their_definitions() {
        let r = run("a", None).row(2);
        assert!((r.plastic_index() - 2.0 / 3.0).abs() < 1e-15);
        assert!((r.friction_index() - 1.0 / 4.0).abs() < 1e-15);
        assert_eq!(run("a", None).row(0).plastic_index(), 0.0);
    }

    #[test]
    fn the_peak_is_the_largest_stress_ratio() {
        let r = run("a", Some(vec![1.0, 3.0, 2.5, 3.0, 1.0]));
        let (value, row) = r.peak().unwrap();
        assert_eq!(value, 3.0);
        assert_eq!(row.time, 1e-4);
        assert!(run("b", None).peak().is_none());
        let table = ledger_table(&[r]);
        // ALLWK reaches 16 µJ: the table is in µJ; the peak row holds ALLWK, ALLSE, ALLPD
        assert!(table.contains("ALLWK (µJ)"), "{table}");
        assert!(
            table.contains("| a | peak | 0.1000 | 3.0000 | 4.0000 | 1.0000 | 2.0000 |"),
            "{table}"
        );
        assert!(table.contains("| a | end | 0.4000 | – |"), "{table}");
    }

    #[test]
    fn labels_come_from_the_run_directory() {
        assert_eq!(
            default_label(Path::new("out/energy_plastic/results.h5")),
            "energy_plastic"
        );
        assert_eq!(default_label(Path::new("cell.h5")), "cell");
    }

    #[test]
    fn figures_are_drawn_for_two_runs() {
        let dir = std::env::temp_dir().join(format!("mufe_energy_fig_{}", std::process::id()));
        let written =
            draw_energy_figures(&[run("elastic", None), run("plastic", None)], &dir).unwrap();
        assert_eq!(written.len(), 4);
        for p in &written {
            assert_eq!(&std::fs::read(p).unwrap()[1..4], b"PNG");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_history_column_shorter_than_time_is_an_input_error_naming_it() {
        let dir = std::env::temp_dir().join(format!("mufe_short_column_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("results.h5");
        {
            let file = hdf5::File::create(&path).unwrap();
            let history = file.create_group("history").unwrap();
            for name in [
                "time",
                "external_work",
                "kinetic_energy",
                "recoverable_strain_energy",
                "plastic_dissipation",
                "friction_dissipation",
                "damping_dissipation",
                "energy_balance",
            ] {
                // as a job killed in the middle of a flush leaves it
                let rows = if name == "friction_dissipation" { 2 } else { 3 };
                let values = vec![1.0f64; rows];
                history
                    .new_dataset_builder()
                    .with_data(&values)
                    .create(name)
                    .unwrap();
            }
        }
        let e = RunHistory::read(&path, "x").err().unwrap();
        assert_eq!(e.exit_code(), 2);
        let line = e.to_string();
        assert!(
            line.contains("/history/friction_dissipation: has 2 rows where /history/time has 3"),
            "{line}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_missing_file_is_an_input_error_naming_it() {
        let e = RunHistory::read(Path::new("/nonexistent/results.h5"), "x")
            .err()
            .unwrap();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("/nonexistent/results.h5"), "{e}");
    }
}
