//! Coulomb friction at one contact point: elastic tangential predictor and return to the
//! slip cone (the classical return mapping of elasto-plasticity with the slip condition
//! |t| ≤ μ p as the yield surface).
//!
//! Per step, with the traction `t_old` of the previous step already rotated onto the
//! current tangent plane ([`rotate_onto_plane`]) and the tangential increment `Δu_t` of
//! the slave's displacement relative to the master:
//!
//! - trial: t* = t_old − ε_t Δu_t (the tangential spring resists the relative motion);
//! - stick if |t*| ≤ μ p: t = t*;
//! - slip otherwise: t = μ p t*/|t*|, plastic slip Δs = −(|t*| − μ p)/ε_t · t*/|t*|.
//!
//! The dissipated energy per unit area is exactly −t·Δs = μ p (|t*| − μ p)/ε_t ≥ 0 (force
//! × slip increment); the elastic energy left in the tangential spring is ½|t|²/ε_t.

use crate::math::{dot, norm, scale, sub};

/// Outcome of [`return_map`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReturnMap {
    /// New tangential traction on the slave (Pa).
    pub traction: [f64; 3],
    /// Plastic slip increment of the slave relative to the master (m); zero when sticking.
    pub slip: [f64; 3],
    /// Energy dissipated per unit area in this increment, −t·Δs (J/m²), ≥ 0.
    pub dissipation: f64,
    /// True when the trial traction was inside the cone.
    pub sticking: bool,
}

/// Elastic predictor / return mapping (see module docs). `limit` = μ p ≥ 0 (Pa),
/// `stiffness` = ε_t > 0 (Pa/m), `du_t` = tangential relative displacement increment (m).
#[inline]
pub fn return_map(t_old: [f64; 3], du_t: [f64; 3], stiffness: f64, limit: f64) -> ReturnMap {
    let trial = sub(t_old, scale(du_t, stiffness));
    let m = norm(trial);
    if m <= limit {
        return ReturnMap {
            traction: trial,
            slip: [0.0; 3],
            dissipation: 0.0,
            sticking: true,
        };
    }
    let dir = scale(trial, 1.0 / m);
    let excess = m - limit;
    ReturnMap {
        traction: scale(dir, limit),
        slip: scale(dir, -excess / stiffness),
        dissipation: limit * excess / stiffness,
        sticking: false,
    }
}

/// Projects a stored traction onto the tangent plane of the unit normal `n`, keeping its
/// magnitude (so that the history stays objective when the contact plane tilts, e.g. under
/// rolling). A traction (nearly) parallel to `n` is dropped.
#[inline]
pub fn rotate_onto_plane(t: [f64; 3], n: [f64; 3]) -> [f64; 3] {
    let m = norm(t);
    if m == 0.0 {
        return t;
    }
    let p = sub(t, scale(n, dot(t, n)));
    let pm = norm(p);
    if pm <= 1e-12 * m {
        return [0.0; 3];
    }
    scale(p, m / pm)
}

/// Tangential part of a vector with respect to the unit normal `n`.
#[inline]
pub fn tangential(v: [f64; 3], n: [f64; 3]) -> [f64; 3] {
    sub(v, scale(n, dot(v, n)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sticks_below_the_cone() {
        let r = return_map([1.0, 0.0, 0.0], [1e-3, 0.0, 0.0], 100.0, 5.0);
        assert!(r.sticking);
        assert_eq!(r.traction, [0.9, 0.0, 0.0]);
        assert_eq!(r.dissipation, 0.0);
        assert_eq!(r.slip, [0.0; 3]);
    }

    #[test]
    fn slips_on_the_cone_and_dissipates_force_times_slip() {
        let (eps, limit) = (1.0e4, 3.0);
        // Already sliding along +x with |t| = μp; the slave moves further by Δu along −x…
        let du = [-2.0e-3, 1.0e-3, 0.0];
        let r = return_map([limit, 0.0, 0.0], du, eps, limit);
        assert!(!r.sticking);
        assert!((norm(r.traction) - limit).abs() < 1e-12);
        // dissipation = −t·Δs = |t|·|Δs|
        let d = -dot(r.traction, r.slip);
        assert!((r.dissipation - d).abs() < 1e-12 * d.max(1.0));
        assert!((d - limit * norm(r.slip)).abs() < 1e-12);
        // elastic part + plastic part = total increment (trial decomposition)
        let elastic = scale(sub(r.traction, [limit, 0.0, 0.0]), -1.0 / eps);
        let total = [
            elastic[0] + r.slip[0],
            elastic[1] + r.slip[1],
            elastic[2] + r.slip[2],
        ];
        for i in 0..3 {
            assert!((total[i] - du[i]).abs() < 1e-15, "{total:?} vs {du:?}");
        }
    }

    #[test]
    fn steady_sliding_dissipates_mu_p_times_distance() {
        // Start at rest, push steadily: stick until |t| = μp, then dissipate exactly μp per
        // unit slip distance.
        let (eps, limit, step) = (1.0e6, 2.0, 1.0e-7);
        let mut t = [0.0; 3];
        let mut dissipated = 0.0;
        let mut stuck_steps = 0;
        for _ in 0..1000 {
            let r = return_map(t, [step, 0.0, 0.0], eps, limit);
            if r.sticking {
                stuck_steps += 1;
            }
            t = r.traction;
            dissipated += r.dissipation;
        }
        // elastic stick range limit/eps = 2e-6 = 20 steps (the 20th lands on the cone up to
        // round-off)
        assert!((19..=20).contains(&stuck_steps), "{stuck_steps}");
        let moved = 1000.0 * step;
        let expected = limit * (moved - limit / eps);
        assert!(
            (dissipated - expected).abs() < 1e-9 * expected,
            "{dissipated} vs {expected}"
        );
        assert!((t[0] + limit).abs() < 1e-12);
    }

    #[test]
    fn rotation_keeps_magnitude_in_the_new_plane() {
        let t = [3.0, 0.0, 0.0];
        let a: f64 = 0.1;
        let n = [a.sin(), 0.0, a.cos()];
        let r = rotate_onto_plane(t, n);
        assert!(dot(r, n).abs() < 1e-14);
        assert!((norm(r) - 3.0).abs() < 1e-14);
        assert_eq!(
            rotate_onto_plane([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]),
            [0.0; 3]
        );
    }
}
