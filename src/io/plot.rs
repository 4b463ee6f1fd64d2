//! PNG line plots (plotters): FE curves over theory curves, speed against error.

use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::path::Path;

/// One curve of a plot.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// Theory curves are drawn as thick lines (black, then greys told apart by dashes; an
    /// empty label continues the previous theory curve's style and has no legend entry),
    /// FE curves as coloured markers + lines.
    pub theory: bool,
}

/// Axis scaling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scale {
    Linear,
    Log,
}

/// A 2-D plot description.
#[derive(Debug, Clone)]
pub struct Plot<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_scale: Scale,
    pub y_scale: Scale,
    pub series: Vec<Series>,
}

/// Styles of successive labelled theory curves: colour and (dash, gap) in pixels.
const THEORY_STYLES: [(RGBColor, Option<(u32, u32)>); 4] = [
    (BLACK, None),
    (RGBColor(150, 150, 150), None),
    (RGBColor(90, 90, 90), Some((12, 8))),
    (RGBColor(160, 120, 70), Some((4, 6))),
];

/// Nine colours (no greys: those are the theory curves'), so `mufe plot` of four runs with
/// two quantities each draws eight distinguishable curves.
const PALETTE: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
];

fn bounds(series: &[Series], scale: Scale, pick: impl Fn(&(f64, f64)) -> f64) -> (f64, f64) {
    let vals = series
        .iter()
        .flat_map(|s| s.points.iter().map(&pick))
        .filter(|v| v.is_finite() && (scale == Scale::Linear || *v > 0.0));
    let (mut lo, mut hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if lo == hi {
        lo -= 0.5 * lo.abs().max(1e-30);
        hi += 0.5 * hi.abs().max(1e-30);
    }
    match scale {
        Scale::Linear => {
            let pad = 0.05 * (hi - lo);
            (lo - pad, hi + pad)
        }
        Scale::Log => (lo / 1.2, hi * 1.2),
    }
}

/// Draws the plot into a PNG of 1000×700 pixels.
pub fn draw(path: &Path, plot: &Plot) -> Result<(), String> {
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (x0, x1) = bounds(&plot.series, plot.x_scale, |p| p.0);
    let (y0, y1) = bounds(&plot.series, plot.y_scale, |p| p.1);
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(plot.title, ("sans-serif", 26))
        .margin(20)
        .x_label_area_size(55)
        .y_label_area_size(90);
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(plot.x_label)
                .y_desc(plot.y_label)
                .x_label_formatter(&|v| tick_label(*v))
                .y_label_formatter(&|v| tick_label(*v))
                .label_style(("sans-serif", 16))
                .axis_desc_style(("sans-serif", 20))
                .draw()
                .map_err(|e| e.to_string())?;
            let mut colour = 0;
            let mut theory_count = 0;
            for s in &plot.series {
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| p.0.is_finite() && p.1.is_finite())
                    .filter(|p| {
                        (plot.x_scale == Scale::Linear || p.0 > 0.0)
                            && (plot.y_scale == Scale::Linear || p.1 > 0.0)
                    })
                    .collect();
                if s.theory {
                    // theory curves in greys, told apart by dashes; an unlabelled curve
                    // continues the previous one (e.g. the second branch of a loop)
                    if !s.label.is_empty() || theory_count == 0 {
                        theory_count += 1;
                    }
                    let (c, dash) = THEORY_STYLES[(theory_count - 1) % THEORY_STYLES.len()];
                    let style = c.stroke_width(3);
                    let drawn = match dash {
                        None => chart.draw_series(LineSeries::new(pts, style)),
                        Some((on, off)) => {
                            chart.draw_series(DashedLineSeries::new(pts, on, off, style))
                        }
                    }
                    .map_err(|e| e.to_string())?;
                    if !s.label.is_empty() {
                        drawn.label(s.label.clone()).legend(move |(x, y)| {
                            let (on, off) = dash.unwrap_or((24, 1));
                            DashedPathElement::new(vec![(x, y), (x + 24, y)], on, off, style)
                        });
                    }
                } else {
                    let c = PALETTE[colour % PALETTE.len()];
                    colour += 1;
                    chart
                        .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                        .map_err(|e| e.to_string())?;
                    chart
                        .draw_series(pts.iter().map(|p| Circle::new(*p, 3, c.filled())))
                        .map_err(|e| e.to_string())?
                        .label(s.label.clone())
                        .legend(move |(x, y)| Circle::new((x + 10, y), 4, c.filled()));
                }
            }
            chart
                .configure_series_labels()
                .label_font(("sans-serif", 16))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperLeft)
                .draw()
                .map_err(|e| e.to_string())?;
        }};
    }
    match (plot.x_scale, plot.y_scale) {
        (Scale::Linear, Scale::Linear) => body!(builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?),
        (Scale::Log, Scale::Log) => body!(builder
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(|e| e.to_string())?),
        (Scale::Log, Scale::Linear) => body!(builder
            .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
            .map_err(|e| e.to_string())?),
        (Scale::Linear, Scale::Log) => body!(builder
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(|e| e.to_string())?),
    }
    root.present()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(())
}

/// A tick value as short text that tells neighbouring ticks apart: up to four decimals
/// between 10⁻³ and 10⁵ ("0.5", "2.25", "3000"), else a mantissa of up to three
/// significant digits ("1.25e-5"). Plotters' own labels round a strain axis of 10⁻⁵ steps to
/// "0.0, 0.0, 0.00001, 0.00001, …".
pub fn tick_label(v: f64) -> String {
    let trim = |t: String| -> String {
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    if (1e-3..1e5).contains(&v.abs()) {
        return trim(format!("{v:.4}"));
    }
    let text = format!("{v:.2e}");
    let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
    format!("{}e{exponent}", trim(mantissa.to_string()))
}

/// The SI prefix that shows energies up to `largest` (J) as numbers between 1 and 1000:
/// (unit, multiplier from joules).
pub fn energy_unit(largest: f64) -> (&'static str, f64) {
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
    use super::*;

    #[test]
    fn draws_a_png_with_theory_and_fe_curves() {
        let dir = crate::testing::TestDir::new("plot");
        let path = dir.join("p.png");
        let theory = Series {
            label: "theory".into(),
            points: (1..50).map(|i| (i as f64, (i as f64).powf(1.5))).collect(),
            theory: true,
        };
        let fe = Series {
            label: "FE".into(),
            points: (1..50)
                .step_by(5)
                .map(|i| (i as f64, 1.02 * (i as f64).powf(1.5)))
                .collect(),
            theory: false,
        };
        draw(
            &path,
            &Plot {
                title: "test",
                x_label: "x",
                y_label: "y",
                x_scale: Scale::Log,
                y_scale: Scale::Log,
                series: vec![theory, fe],
            },
        )
        .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(bytes.len() > 5000);
    }

    #[test]
    fn tick_labels_tell_small_ticks_apart() {
        let strain: Vec<String> = [0.0, 2.5e-6, 5e-6, 1e-5, 1.25e-5, 5e-5]
            .map(tick_label)
            .to_vec();
        assert_eq!(strain, ["0", "2.5e-6", "5e-6", "1e-5", "1.25e-5", "5e-5"]);
        assert_eq!(tick_label(0.5), "0.5");
        assert_eq!(tick_label(2.25), "2.25");
        assert_eq!(tick_label(3000.0), "3000");
        assert_eq!(tick_label(-0.002), "-0.002");
        assert_eq!(tick_label(2.0e5), "2e5");
    }

    #[test]
    fn energies_are_shown_between_one_and_a_thousand() {
        assert_eq!(energy_unit(2.5).0, "J");
        assert_eq!(energy_unit(0.7).0, "mJ");
        assert_eq!(energy_unit(3.2e-6).0, "µJ");
        assert_eq!(energy_unit(4.0e-10).0, "pJ");
        assert_eq!(energy_unit(0.0).0, "fJ");
    }
}
