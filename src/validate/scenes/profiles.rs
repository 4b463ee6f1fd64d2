//! Velocity histories of the generated scenes: raised-cosine trapezoids and the Hertz
//! plates' ramps, as the piecewise-linear points a scene's `history` holds.

use super::{invalid, HertzParams, SceneInputs};
use crate::error::{num, InputError};

/// `x` in C/Python `%.{prec}e` style (`7.500000000e-07`): a sign and two exponent digits.
pub(super) fn sci(x: f64, prec: usize) -> String {
    let s = format!("{x:.prec$e}");
    match s.split_once('e') {
        Some((mant, exp)) => {
            let e: i32 = exp.parse().unwrap_or(0);
            format!("{mant}e{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
        }
        None => s,
    }
}

/// Points of the raised-cosine ramps.
const RAMP_POINTS: usize = 8;

pub(super) type Points = Vec<(f64, f64)>;

/// Velocity-time points moving `distance` (signed) from t0 at speed `vmax`: raised-cosine
/// ramps of duration `ramp` up and down, constant speed between. Returns (points, end time).
pub(super) fn trapezoid(
    t0: f64,
    distance: f64,
    vmax: f64,
    ramp: f64,
    what: &str,
) -> Result<(Points, f64), String> {
    let v = vmax.copysign(distance);
    // each raised-cosine ramp covers v·ramp/2
    let cruise = distance.abs() / vmax - ramp;
    if !(cruise > 0.0 && ramp >= 0.0) {
        return Err(format!(
            "{what}: the motion ({} over ramps of {} s at {}) is too short for its ramps",
            num(distance),
            num(ramp),
            num(vmax)
        ));
    }
    let n = RAMP_POINTS as f64;
    let mut pts: Points = (0..=RAMP_POINTS)
        .map(|k| {
            let k = k as f64;
            (
                t0 + ramp * k / n,
                v * 0.5 * (1.0 - (std::f64::consts::PI * k / n).cos()),
            )
        })
        .collect();
    let t2 = t0 + ramp + cruise;
    pts.extend((0..=RAMP_POINTS).map(|k| {
        let k = k as f64;
        (
            t2 + ramp * k / n,
            v * 0.5 * (1.0 + (std::f64::consts::PI * k / n).cos()),
        )
    }));
    Ok((pts, t2 + ramp))
}

pub(super) fn fmt_hist(points: &[(f64, f64)], axis: usize) -> String {
    let times: Vec<String> = points.iter().map(|p| sci(p.0, 9)).collect();
    let values: Vec<String> = points
        .iter()
        .map(|p| {
            let mut v = [0.0; 3];
            v[axis] = p.1;
            format!("[{}, {}, {}]", sci(v[0], 6), sci(v[1], 6), sci(v[2], 6))
        })
        .collect();
    format!(
        "{{ times = [{}], values = [{}] }}",
        times.join(", "),
        values.join(", ")
    )
}

/// Piecewise-linear value of a velocity history at t (held constant outside).
pub(super) fn value_at(pts: &[(f64, f64)], t: f64) -> f64 {
    if t <= pts[0].0 {
        return pts[0].1;
    }
    for w in pts.windows(2) {
        let ((t0, v0), (t1, v1)) = (w[0], w[1]);
        if t0 <= t && t <= t1 {
            return if t1 > t0 {
                v0 + (v1 - v0) * (t - t0) / (t1 - t0)
            } else {
                v1
            };
        }
    }
    pts[pts.len() - 1].1
}

/// Normal (z) and tangential (x) velocity histories on one time base.
pub(super) fn merge(z: &[(f64, f64)], x: &[(f64, f64)]) -> String {
    let mut times: Vec<f64> = z.iter().chain(x.iter()).map(|p| p.0).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let ts: Vec<String> = times.iter().map(|&t| sci(t, 9)).collect();
    let vs: Vec<String> = times
        .iter()
        .map(|&t| {
            format!(
                "[{}, 0.0, {}]",
                sci(value_at(x, t), 6),
                sci(value_at(z, t), 6)
            )
        })
        .collect();
    format!(
        "{{ times = [{}], values = [{}] }}",
        ts.join(", "),
        vs.join(", ")
    )
}
/// away from the poles. Returns (velocity points, duration, description).
pub(super) fn plate_ramp(
    inputs: &SceneInputs,
    p: &HertzParams,
    v_plate: f64,
    ramp: f64,
    gap: f64,
    delta_end: f64,
) -> Result<(Points, f64, String), InputError> {
    let (up, travel_ramp): (Points, f64) = if ramp > 0.0 {
        let n = RAMP_POINTS as f64;
        (
            (0..=RAMP_POINTS)
                .map(|k| {
                    let k = k as f64;
                    (
                        ramp * k / n,
                        v_plate * 0.5 * (1.0 - (std::f64::consts::PI * k / n).cos()),
                    )
                })
                .collect(),
            0.5 * v_plate * ramp,
        )
    } else {
        (vec![(0.0, v_plate)], 0.0)
    };
    let duration = ramp + (gap + delta_end - travel_ramp) / v_plate;
    if duration <= ramp {
        return Err(invalid(
            inputs,
            "hertz",
            "the plate travel ends inside the speed ramp".into(),
        ));
    }
    let motion = if ramp > 0.0 {
        format!(
            "raised-cosine ramp to {:.4} m/s = {:.3e} c_p over {:.3} µs, then constant",
            v_plate,
            p.v_plate,
            ramp * 1e6
        )
    } else {
        format!(
            "constant {v_plate:.4} m/s = {:.3e} c_p from t = 0",
            p.v_plate
        )
    };
    Ok((up, duration, motion))
}

/// Points of the exponential plate speed.
const EXPONENTIAL_POINTS: usize = 48;

/// Exponential drive: δ(t) = δ0 (e^{t/τ} − 1) from first touch at t = 0 (no gap), speed
/// sampled piecewise linearly. Returns (velocity points, duration, description).
pub(super) fn plate_exponential(
    inputs: &SceneInputs,
    p: &HertzParams,
    delta_end: f64,
) -> Result<(Points, f64, String), InputError> {
    let u = inputs.units();
    let (tau, delta0) = (p.tau * u.time, p.delta0 * u.length);
    if !(delta0 > 0.0 && delta0 < delta_end && p.gap == 0.0) {
        return Err(invalid(
            inputs,
            "hertz",
            "the exponential drive needs 0 < delta0 < a_end² and gap = 0".into(),
        ));
    }
    let duration = tau * (1.0 + delta_end / delta0).ln();
    let n = EXPONENTIAL_POINTS as f64;
    // the piecewise-linear speed overestimates the travel by ≈ (Δt/τ)²/12 (0.1 % with the
    // defaults): the plates reach δ_end a little before the end of the duration
    let up: Points = (0..=EXPONENTIAL_POINTS)
        .map(|k| {
            let t = duration * k as f64 / n;
            (t, delta0 / tau * (t / tau).exp())
        })
        .collect();
    let motion = format!(
        "exponential, δ = δ0 (e^(t/τ) − 1), τ = {:.4} µs = {:.4} R/c_p, δ0 = {:.4} µm,\n\
         # from {:.3e} to {:.4} m/s",
        tau * 1e6,
        p.tau,
        delta0 * 1e6,
        delta0 / tau,
        (delta_end + delta0) / tau
    );
    Ok((up, duration, motion))
}
