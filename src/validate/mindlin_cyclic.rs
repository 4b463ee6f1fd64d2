//! `mindlin_cyclic`: a full tangential cycle 0 → +δa → −δa → +δa at constant N between two
//! identical spheres (the `mindlin` scene with amplitude δa < δt,max, docs/THEORY.md §2).
//! The run is the two-sphere case's ([`super::two_sphere`]); this module judges the cycle:
//!
//! - the curve against Mindlin–Deresiewicz loading followed by the Masing branches from
//!   each reversal, the reversals taken where the FE drive reversed and the reference
//!   force there from the reference itself (max |Q − Q_MDM| / μN over the whole cycle);
//! - the area of the closed loop ∮ Q dδt, from the first reversal back to the same drive
//!   position, against what the ledger says was dissipated over the same interval,
//!   Δ(ALLFD + ALLVD). The stored energy at both ends is the same (Masing: the state
//!   repeats), so the two agree when the friction and damping work are booked exactly.
//!   The closed-form loop area is reported beside it.

use super::reference::Mindlin;
use crate::error::{MufeError, Result};
use serde_json::json;

/// Largest allowed |∮Q dδt − Δ(ALLFD + ALLVD)| / ∮Q dδt.
pub const LOOP_TOLERANCE: f64 = 0.02;

/// One sample of the tangential phase: drive displacement δt (m), contact force Q (N),
/// and ALLFD + ALLVD so far (J).
#[derive(Debug, Clone, Copy)]
pub struct CyclePoint {
    pub x: f64,
    pub q: f64,
    pub dissipated: f64,
}

/// The verdict on one cycle.
pub struct CycleAnalysis {
    /// max |Q − Q_MDM| / μN over the cycle.
    pub error: f64,
    /// (δt/δt,max, signed error in % of μN) along the cycle.
    pub error_curve: Vec<(f64, f64)>,
    pub loop_balance_error: f64,
    pub details: serde_json::Map<String, serde_json::Value>,
}

/// Closed-form area of a symmetric Mindlin–Deresiewicz–Masing loop between ±δa for the
/// pair described by `md` (docs/THEORY.md §2): (24/5) μN δt,max [1 − (1−x)^{5/3} −
/// (5x/6)(1 + (1−x)^{2/3})] with x = Q*/μN below gross slip, 4μN(δa − 0.8 δt,max) above.
pub fn loop_area(md: &Mindlin, amplitude: f64) -> f64 {
    let (mu_n, d) = (md.mu * md.normal_force, md.slip_displacement);
    if amplitude >= d {
        return 4.0 * mu_n * (amplitude - 0.8 * d);
    }
    let x = md.loading(amplitude) / mu_n;
    let s = 1.0 - x;
    4.8 * mu_n * d * (1.0 - s.powf(5.0 / 3.0) - 5.0 * x / 6.0 * (1.0 + s.powf(2.0 / 3.0)))
}

/// Index of the first reversal of x at or after `from` in direction `sign` (the running
/// extreme, once x has come back from it by 1 % of `span`).
fn reversal(points: &[CyclePoint], from: usize, sign: f64, span: f64) -> Option<usize> {
    let mut best = from;
    for (i, p) in points.iter().enumerate().skip(from) {
        if sign * p.x >= sign * points[best].x {
            best = i;
        } else if sign * (points[best].x - p.x) > 0.01 * span {
            return Some(best);
        }
    }
    None
}

/// Judges the cycle in `points` (the whole tangential phase, in time order) against the
/// reference `md` (evaluated with the measured N).
pub fn analyse(points: &[CyclePoint], md: &Mindlin) -> Result<CycleAnalysis> {
    let mu_n = md.mu * md.normal_force;
    let span = points.iter().map(|p| p.x.abs()).fold(0.0, f64::max);
    let incomplete = |what: &str| {
        MufeError::Run(format!(
            "mindlin_cyclic: the drive history has no {what}; the scene must run 0 → +δa → −δa → +δa"
        ))
    };
    let top = reversal(points, 0, 1.0, span).ok_or_else(|| incomplete("first reversal"))?;
    let bottom = reversal(points, top, -1.0, span).ok_or_else(|| incomplete("second reversal"))?;
    // the loop closes where the reload first reaches the first reversal's position again
    let close = (bottom..points.len())
        .find(|&i| points[i].x >= points[top].x)
        .ok_or_else(|| incomplete("reload back to +δa"))?;
    let (x_top, x_bottom) = (points[top].x, points[bottom].x);
    let q_top = md.loading(x_top);
    let q_bottom = md.unloading(x_top, q_top, x_bottom);
    let reference = |i: usize, x: f64| {
        if i <= top {
            md.loading(x)
        } else if i <= bottom {
            md.unloading(x_top, q_top, x)
        } else {
            md.unloading(x_bottom, q_bottom, x)
        }
    };
    let (mut error, mut error_curve) = (0.0f64, Vec::new());
    for (i, p) in points.iter().enumerate().take(close + 1) {
        let e = (p.q - reference(i, p.x)) / mu_n;
        error = error.max(e.abs());
        error_curve.push((p.x / md.slip_displacement, 100.0 * e));
    }
    // ∮ Q dδt from the first reversal to the closing point (trapezoids; the last one
    // interpolated to x_top so that the loop is closed exactly)
    let mut area = 0.0;
    for w in points[top..=close].windows(2) {
        area += 0.5 * (w[0].q + w[1].q) * (w[1].x - w[0].x);
    }
    let (a, b) = (points[close - 1], points[close]);
    let overshoot = (b.x - x_top) / (b.x - a.x).max(f64::MIN_POSITIVE);
    let q_at_top = b.q + overshoot * (a.q - b.q);
    area -= 0.5 * (b.q + q_at_top) * (b.x - x_top);
    let dissipated_at_top = b.dissipated + overshoot * (a.dissipated - b.dissipated);
    let dissipated = dissipated_at_top - points[top].dissipated;
    let loop_balance_error = (area - dissipated).abs() / area.abs().max(f64::MIN_POSITIVE);
    let amplitude = 0.5 * (x_top - x_bottom);
    let theory = loop_area(md, amplitude);
    let mut details = serde_json::Map::new();
    details.insert(
        "amplitude_over_slip_displacement".into(),
        json!(amplitude / md.slip_displacement),
    );
    details.insert("loop_area_j".into(), json!(area));
    details.insert("ledger_friction_plus_damping_j".into(), json!(dissipated));
    details.insert("loop_balance_error".into(), json!(loop_balance_error));
    details.insert("loop_area_theory_j".into(), json!(theory));
    details.insert("loop_area_over_theory".into(), json!(area / theory));
    Ok(CycleAnalysis {
        error,
        error_curve,
        loop_balance_error,
        details,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Mindlin {
        Mindlin {
            mu: 0.3,
            normal_force: 2.0,
            slip_displacement: 1e-6,
        }
    }

    /// A cycle sampled from the reference itself, with the dissipation it implies: zero
    /// curve error, loop area equal to the closed form and to the booked dissipation.
    #[test]
    fn an_exact_masing_cycle_passes_and_matches_the_closed_form() {
        let md = unit();
        let da = 0.8 * md.slip_displacement;
        let n = 4000;
        let mut xs: Vec<f64> = (0..=n).map(|i| da * i as f64 / n as f64).collect();
        xs.extend((1..=2 * n).map(|i| da - 2.0 * da * i as f64 / (2 * n) as f64));
        xs.extend((1..=2 * n).map(|i| -da + 2.0 * da * i as f64 / (2 * n) as f64));
        let q_top = md.loading(da);
        let q_bottom = md.unloading(da, q_top, -da);
        let mut points = Vec::new();
        let mut dissipated = 0.0;
        for (i, &x) in xs.iter().enumerate() {
            let q = if i <= n {
                md.loading(x)
            } else if i <= 3 * n {
                md.unloading(da, q_top, x)
            } else {
                md.unloading(-da, q_bottom, x)
            };
            if let Some(p) = points.last() {
                let p: &CyclePoint = p;
                if i > n {
                    dissipated += 0.5 * (p.q + q) * (x - p.x);
                }
            }
            points.push(CyclePoint { x, q, dissipated });
        }
        let a = analyse(&points, &md).unwrap();
        assert!(a.error < 1e-12, "curve error {}", a.error);
        assert!(a.loop_balance_error < 1e-9);
        let area = a.details["loop_area_j"].as_f64().unwrap();
        let theory = loop_area(&md, da);
        assert!((area / theory - 1.0).abs() < 1e-5, "{area} vs {theory}");
        // a force offset of 10 % of μN shows as a 10 % curve error
        let shifted: Vec<CyclePoint> = points
            .iter()
            .map(|p| CyclePoint {
                q: p.q + 0.1 * md.mu * md.normal_force,
                ..*p
            })
            .collect();
        let b = analyse(&shifted, &md).unwrap();
        assert!((b.error - 0.1).abs() < 1e-9);
    }

    /// Above gross slip the loop is 4μN(δa − 0.8 δt,max); the two forms meet at δa = δt,max.
    #[test]
    fn closed_form_is_continuous_at_gross_slip() {
        let md = unit();
        let d = md.slip_displacement;
        let below = loop_area(&md, d * (1.0 - 1e-9));
        let above = loop_area(&md, d);
        assert!((below / above - 1.0).abs() < 1e-4, "{below} vs {above}");
        assert!((above - 0.8 * md.mu * md.normal_force * d).abs() < 1e-15);
    }

    #[test]
    fn a_cycle_without_its_reversals_is_an_error() {
        let md = unit();
        let points: Vec<CyclePoint> = (0..100)
            .map(|i| CyclePoint {
                x: i as f64 * 1e-8,
                q: 0.0,
                dissipated: 0.0,
            })
            .collect();
        assert!(analyse(&points, &md).is_err());
    }
}
