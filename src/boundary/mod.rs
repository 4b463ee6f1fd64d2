//! Prescribed motions of node sets: rigid driving (translation + rotation about a moving
//! centre) of all or part of a grain, or prescribed translation components. The solver
//! overrides the driven components of v_{n+½} so that the nodes land exactly on their
//! prescribed positions at t_{n+1}, and records the reaction force and moment needed.

pub mod servo;
pub mod stages;

use crate::scene::History3;
use serde::{Deserialize, Serialize};

impl History3 {
    /// Piecewise-linear value at t (held constant outside the given times).
    pub fn value_at(&self, t: f64) -> [f64; 3] {
        let ts = &self.times;
        if t <= ts[0] {
            return self.values[0];
        }
        let last = ts.len() - 1;
        if t >= ts[last] {
            return self.values[last];
        }
        let k = ts.partition_point(|&x| x <= t) - 1;
        let s = (t - ts[k]) / (ts[k + 1] - ts[k]);
        let (a, b) = (self.values[k], self.values[k + 1]);
        [
            a[0] + s * (b[0] - a[0]),
            a[1] + s * (b[1] - a[1]),
            a[2] + s * (b[2] - a[2]),
        ]
    }

    /// ∫₀ᵗ value dt, exact for the piecewise-linear history (constant before the first
    /// time and after the last).
    pub fn integral_to(&self, t: f64) -> [f64; 3] {
        let mut acc = [0.0; 3];
        let mut add = |t0: f64, t1: f64, h: &Self| {
            if t1 > t0 {
                let (a, b) = (h.value_at(t0), h.value_at(t1));
                for i in 0..3 {
                    acc[i] += 0.5 * (a[i] + b[i]) * (t1 - t0);
                }
            }
        };
        let mut prev = 0.0;
        for &tk in &self.times {
            if tk >= t {
                break;
            }
            if tk > prev {
                add(prev, tk, self);
                prev = tk;
            }
        }
        add(prev, t, self);
        acc
    }
}

/// How the driven translation is given.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Translation {
    Fixed,
    Velocity(History3),
    Displacement(History3),
}

impl Translation {
    /// Displacement of the centre from t = 0 to t (m).
    pub fn displacement_at(&self, t: f64) -> [f64; 3] {
        match self {
            Translation::Fixed => [0.0; 3],
            Translation::Velocity(h) => h.integral_to(t),
            Translation::Displacement(h) => {
                let u0 = h.value_at(0.0);
                let u = h.value_at(t);
                [u[0] - u0[0], u[1] - u0[1], u[2] - u0[2]]
            }
        }
    }
}

/// A prescribed motion bound to concrete nodes (set up from a `BoundarySpec`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PrescribedMotion {
    pub name: String,
    /// Global node indices driven (ascending).
    pub nodes: Vec<u32>,
    /// Reference positions of those nodes relative to `centre0` (m).
    pub offsets: Vec<[f64; 3]>,
    /// Centre of rotation at t = 0 (m).
    pub centre0: [f64; 3],
    pub translation: Translation,
    pub angular_velocity: Option<History3>,
    /// Driven translation components (all three for rigid motions).
    pub components: [bool; 3],
    /// Rotation at t = 0 (row-major identity); the current one is solver state.
    pub rotation: [f64; 9],
}

/// Rotation matrix exp([θ]×) by Rodrigues' formula (row-major).
pub fn rotation_from_vector(theta: [f64; 3]) -> [f64; 9] {
    let angle = (theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]).sqrt();
    if angle == 0.0 {
        return [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    }
    let k = [theta[0] / angle, theta[1] / angle, theta[2] / angle];
    let (s, c) = angle.sin_cos();
    let v = 1.0 - c;
    [
        c + k[0] * k[0] * v,
        k[0] * k[1] * v - k[2] * s,
        k[0] * k[2] * v + k[1] * s,
        k[1] * k[0] * v + k[2] * s,
        c + k[1] * k[1] * v,
        k[1] * k[2] * v - k[0] * s,
        k[2] * k[0] * v - k[1] * s,
        k[2] * k[1] * v + k[0] * s,
        c + k[2] * k[2] * v,
    ]
}

impl PrescribedMotion {
    /// True when the nodes move as a rigid body (rotation allowed).
    pub fn is_rigid(&self) -> bool {
        self.components == [true; 3]
    }

    /// Centre position at time t (m).
    pub fn centre_at(&self, t: f64) -> [f64; 3] {
        let u = self.translation.displacement_at(t);
        [
            self.centre0[0] + u[0],
            self.centre0[1] + u[1],
            self.centre0[2] + u[2],
        ]
    }

    /// Rotation at t_{n+1} from the one at t_n (`current`): Q ← exp(ω(t_{n+½})Δt)·Q.
    pub fn rotation_after(&self, current: &[f64; 9], t_n: f64, dt: f64) -> [f64; 9] {
        match &self.angular_velocity {
            None => *current,
            Some(h) => {
                let w = h.value_at(t_n + 0.5 * dt);
                let inc = rotation_from_vector([w[0] * dt, w[1] * dt, w[2] * dt]);
                crate::math::mat_mul(&inc, current)
            }
        }
    }

    /// Prescribed position of driven node k at a time with centre `c` and rotation `q`.
    #[inline]
    pub fn position(&self, k: usize, c: &[f64; 3], q: &[f64; 9]) -> [f64; 3] {
        let o = self.offsets[k];
        [
            c[0] + q[0] * o[0] + q[1] * o[1] + q[2] * o[2],
            c[1] + q[3] * o[0] + q[4] * o[1] + q[5] * o[2],
            c[2] + q[6] * o[0] + q[7] * o[1] + q[8] * o[2],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_integral_is_exact_for_ramps() {
        let h = History3 {
            times: vec![1.0, 3.0],
            values: vec![[0.0, 2.0, 1.0], [2.0, 2.0, 1.0]],
        };
        // v_x: 0 until 1, ramps to 2 at 3, then 2: ∫₀⁴ = 0 + 2 + 2 = 4
        let u = h.integral_to(4.0);
        assert!((u[0] - 4.0).abs() < 1e-12);
        assert!((u[1] - 8.0).abs() < 1e-12);
        let u = h.integral_to(2.0); // ∫₁² s ds with v = (t−1): 0.5
        assert!((u[0] - 0.5).abs() < 1e-12);
        assert_eq!(h.value_at(2.0), [1.0, 2.0, 1.0]);
    }

    #[test]
    fn rodrigues_is_orthonormal() {
        let q = rotation_from_vector([0.3, -1.2, 0.7]);
        let qtq = crate::math::mat_mul(&[q[0], q[3], q[6], q[1], q[4], q[7], q[2], q[5], q[8]], &q);
        for i in 0..3 {
            for j in 0..3 {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((qtq[3 * i + j] - e).abs() < 1e-14);
            }
        }
    }
}
