//! The velocity v_{n+½} while a step builds it.
//!
//! The central-difference predictor is v_{n+½} = v_{n−½} + Δt f/m; the boundary stage then
//! overwrites it where prescribed motions and walls act, and the integrator moves every
//! node with it. Stored for every node, the prediction is a pass over all nodes that
//! writes 24 bytes each and the integrator reads them back, which on the 2000-sphere block
//! was a tenth of the step outside the element kernel. A step therefore stores only the
//! nodes that motions and walls change, and every reader predicts the others where it
//! reads them, from exactly the same expression: the values are the same to the bit.
//!
//! The same holds for gravity and mass-proportional damping ([`BodyForces`]): they are
//! added to a node's force where its prediction is read, not in a pass of their own that
//! rewrites every force (2.7 ms of a 50 ms step of the damped 2000-sphere block).

use crate::lanes::{touch_value, NodeForce};

/// A grain's rigid-body velocity field v(x) = v_c + ω × (x − x_c), from its linear and
/// angular momentum (so that damping relative to it exerts no net force or moment).
#[derive(Debug, Clone, Copy, Default)]
pub struct RigidVelocity {
    pub centre: [f64; 3],
    pub velocity: [f64; 3],
    pub omega: [f64; 3],
}

impl RigidVelocity {
    #[inline(always)]
    pub fn at(&self, x: &[f64; 3]) -> [f64; 3] {
        let r = [
            x[0] - self.centre[0],
            x[1] - self.centre[1],
            x[2] - self.centre[2],
        ];
        let w = &self.omega;
        [
            self.velocity[0] + w[1] * r[2] - w[2] * r[1],
            self.velocity[1] + w[2] * r[0] - w[0] * r[2],
            self.velocity[2] + w[0] * r[1] - w[1] * r[0],
        ]
    }
}

/// Gravity on the physical mass and mass-proportional damping, the forces a node has
/// besides its internal and contact ones:
///
/// f_body = m_p g + f_d,  f_d = −α m v − α_def m (v − v_rigid(x)),
///
/// with m the integrator's (scaled) mass, m_p the physical one (mass added by scaling is
/// numerical and weighs nothing), v = v_{n−½}, x = x_n and v_rigid the node's grain's
/// rigid-body velocity (no net force or moment on the grain).
#[derive(Clone, Copy)]
pub struct BodyForces<'a> {
    /// g (m/s²).
    pub gravity: [f64; 3],
    /// α (1/s).
    pub alpha: f64,
    /// α_def (1/s); 0 skips the rigid velocities.
    pub deformation_damping: f64,
    /// m_p per node (kg).
    pub physical_mass: &'a [f64],
    /// Each node's grain, indexing `rigid`.
    pub node_grain: &'a [u32],
    /// Each grain's rigid-body velocity from x_n, v_{n−½}.
    pub rigid: &'a [RigidVelocity],
}

impl BodyForces<'_> {
    /// Whether g is anything but +0 in every component. Without gravity m_p g is +0 for
    /// every node, so the passes skip reading m_p and still add the same bits.
    #[inline(always)]
    pub fn weighs(&self) -> bool {
        self.gravity.iter().any(|g| g.to_bits() != 0)
    }

    /// m_p g of node `n` (N).
    #[inline(always)]
    pub fn weight(&self, n: usize) -> [f64; 3] {
        if self.weighs() {
            let mp = self.physical_mass[n];
            self.gravity.map(|g| mp * g)
        } else {
            [0.0; 3]
        }
    }

    /// f_d of node `n` at x, v with integrator mass m (N).
    #[inline(always)]
    pub fn damping_force(&self, n: usize, x: &[f64; 3], v: &[f64; 3], m: f64) -> [f64; 3] {
        let mut f = std::array::from_fn(|i| self.mass_damping_along(m, v[i]));
        if self.deformation_damping > 0.0 {
            let vr = self.rigid[self.node_grain[n] as usize].at(x);
            for i in 0..3 {
                f[i] = self.add_deformation_damping(f[i], m, v[i], vr[i]);
            }
        }
        f
    }

    /// One component of −α m v for integrator mass m and velocity component v (N). With
    /// [`Self::add_deformation_damping`], the expressions every path evaluates, node by
    /// node or in lanes (which keep the test on α_def out of their loops).
    #[inline(always)]
    pub fn mass_damping_along(&self, m: f64, v: f64) -> f64 {
        -self.alpha * m * v
    }

    /// `f` − α_def m (v − v_rigid) along one axis, v_rigid the grain's rigid velocity
    /// component at the node (N).
    #[inline(always)]
    pub fn add_deformation_damping(&self, f: f64, m: f64, v: f64, v_rigid: f64) -> f64 {
        f - self.deformation_damping * m * (v - v_rigid)
    }

    /// The complete force f + (m_p g + f_d) of node `n` from its internal and contact
    /// force f, and f_d (N).
    #[inline(always)]
    pub fn total_force(
        &self,
        n: usize,
        f: [f64; 3],
        x: &[f64; 3],
        v: &[f64; 3],
        m: f64,
    ) -> ([f64; 3], [f64; 3]) {
        let fd = self.damping_force(n, x, v, m);
        let w = self.weight(n);
        (
            std::array::from_fn(|i| with_body_force(f[i], w[i], fd[i])),
            fd,
        )
    }
}

/// One component of the complete force: f + (m_p g + f_d), in that grouping on every path
/// (N).
#[inline(always)]
pub fn with_body_force(f: f64, weight: f64, damping: f64) -> f64 {
    f + (weight + damping)
}

/// What a node's predicted v_{n+½} is computed from.
#[derive(Clone, Copy)]
pub struct Predictor<'a> {
    /// v_{n−½} (m/s).
    pub v: &'a [[f64; 3]],
    /// The node forces of the step from elements and contacts (N).
    pub force: &'a [NodeForce],
    /// The integrator's nodal masses (kg).
    pub mass: &'a [f64],
    /// Δt (s).
    pub dt: f64,
    /// Gravity and damping, with the positions x_n they depend on; `None` when the step
    /// has neither.
    pub body: Option<(BodyForces<'a>, &'a [[f64; 3]])>,
}

impl<'a> Predictor<'a> {
    pub fn new(v: &'a [[f64; 3]], force: &'a [NodeForce], mass: &'a [f64], dt: f64) -> Self {
        Self {
            v,
            force,
            mass,
            dt,
            body: None,
        }
    }

    /// The same with gravity and damping `body` (if any) acting at positions `x`.
    pub fn with_body_forces(self, body: Option<BodyForces<'a>>, x: &'a [[f64; 3]]) -> Self {
        Self {
            body: body.map(|b| (b, x)),
            ..self
        }
    }

    /// The complete force of node `n`: elements, contacts, gravity and damping (N).
    #[inline(always)]
    pub fn force_at(&self, n: usize) -> [f64; 3] {
        match &self.body {
            None => self.force[n].xyz(),
            Some((b, x)) => {
                b.total_force(n, self.force[n].xyz(), &x[n], &self.v[n], self.mass[n])
                    .0
            }
        }
    }

    /// v_{n−½} + Δt f/m of node `n`.
    #[inline(always)]
    pub fn at(&self, n: usize) -> [f64; 3] {
        predict(self.v[n], self.force_at(n), self.mass[n], self.dt)
    }

    /// Requests the data [`Self::at`] reads for node `n` into the cache.
    #[inline(always)]
    pub fn touch(&self, n: usize) {
        touch_value(self.v, n);
        touch_value(self.force, n);
        touch_value(self.mass, n);
        if let Some((b, x)) = &self.body {
            if b.weighs() {
                touch_value(b.physical_mass, n);
            }
            touch_value(x, n);
        }
    }
}

/// v + Δt f/m, the one expression every path evaluates.
#[inline(always)]
pub fn predict(v: [f64; 3], f: [f64; 3], m: f64, dt: f64) -> [f64; 3] {
    std::array::from_fn(|i| predict_along(v[i], f[i], m, dt))
}

/// One component of [`predict`] (the integrator's lanes evaluate it component-wise).
#[inline(always)]
pub fn predict_along(v: f64, f: f64, m: f64, dt: f64) -> f64 {
    v + dt * f / m
}

/// v_{n+½} of every node: stored where set, else the prediction (module docs).
#[derive(Debug, Default)]
pub struct NextVelocity {
    values: Vec<[f64; 3]>,
    /// Per node: `values` holds its v_{n+½}.
    stored: Vec<bool>,
    /// The nodes marked in `stored`, to clear them for the next step.
    changed: Vec<u32>,
}

impl NextVelocity {
    pub fn new(nodes: usize) -> Self {
        Self {
            values: vec![[0.0; 3]; nodes],
            stored: vec![false; nodes],
            changed: Vec::new(),
        }
    }

    /// Starts a step whose nodes keep their prediction unless set.
    pub fn predict_where_read(&mut self) {
        for &n in &self.changed {
            self.stored[n as usize] = false;
        }
        self.changed.clear();
    }

    /// The stored v_{n+½} of node `n`, `None` where it is the prediction.
    #[inline(always)]
    pub fn stored(&self, n: usize) -> Option<[f64; 3]> {
        self.stored[n].then(|| self.values[n])
    }

    /// Whether any of `nodes` has a stored v_{n+½}.
    #[inline(always)]
    pub fn any_stored(&self, nodes: std::ops::Range<usize>) -> bool {
        self.stored[nodes].iter().any(|&s| s)
    }

    /// v_{n+½} of node `n`.
    #[inline(always)]
    pub fn get(&self, n: usize, predictor: &Predictor) -> [f64; 3] {
        self.stored(n).unwrap_or_else(|| predictor.at(n))
    }

    /// Sets v_{n+½} of node `n`.
    #[inline]
    pub fn set(&mut self, n: usize, v: [f64; 3]) {
        self.values[n] = v;
        if !self.stored[n] {
            self.stored[n] = true;
            self.changed.push(n as u32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn padded(f: &[[f64; 3]]) -> Vec<NodeForce> {
        f.iter().map(|&f| NodeForce::from(f)).collect()
    }

    #[test]
    fn a_node_is_its_prediction_until_set_and_again_next_step() {
        let (v, f, m) = (
            vec![[1.0, 2.0, 3.0]; 3],
            vec![[0.5, -1.0, 2.0]; 3],
            vec![2.0; 3],
        );
        let fp = padded(&f);
        let p = Predictor::new(&v, &fp, &m, 0.1);
        let mut next = NextVelocity::new(3);
        next.predict_where_read();
        let expect = [1.025, 1.95, 3.1];
        assert!((0..3).all(|i| (next.get(1, &p)[i] - expect[i]).abs() < 1e-15));
        next.set(1, [7.0; 3]);
        next.set(1, [8.0; 3]);
        assert_eq!((next.get(0, &p), next.get(1, &p)), (p.at(0), [8.0; 3]));
        assert_eq!(next.stored(2), None);
        next.predict_where_read();
        assert_eq!(next.get(1, &p), p.at(1));
    }

    #[test]
    fn gravity_and_damping_join_the_force_where_it_is_read() {
        let (x, v, f) = (
            vec![[0.0; 3], [0.3, -0.2, 0.5]],
            vec![[0.0; 3], [1.0, -2.0, 0.5]],
            vec![[0.0; 3], [0.5, 1.0, -3.0]],
        );
        let (m, mp, dt) = (vec![1.0, 2.0], vec![1.0, 1.5], 0.01);
        let rigid = [RigidVelocity {
            centre: [0.1, 0.1, 0.1],
            velocity: [0.2, 0.0, -0.1],
            omega: [0.0, 3.0, 1.0],
        }];
        let body = BodyForces {
            gravity: [0.0, 0.0, -9.81],
            alpha: 4.0,
            deformation_damping: 7.0,
            physical_mass: &mp,
            node_grain: &[0, 0],
            rigid: &rigid,
        };
        let fp = padded(&f);
        let p = Predictor::new(&v, &fp, &m, dt).with_body_forces(Some(body), &x);
        // v_rigid at x: v_c + ω × (x − x_c), ω × r with r = (0.2, −0.3, 0.4)
        let vr = [0.2 + 3.0 * 0.4 - 1.0 * -0.3, 1.0 * 0.2, -0.1 - 3.0 * 0.2];
        for i in 0..3 {
            let fd = -4.0 * 2.0 * v[1][i] - 7.0 * 2.0 * (v[1][i] - vr[i]);
            let total = f[1][i] + 1.5 * body.gravity[i] + fd;
            assert!((p.force_at(1)[i] - total).abs() < 1e-12 * total.abs().max(1.0));
            let expect = v[1][i] + dt * total / 2.0;
            assert!((p.at(1)[i] - expect).abs() < 1e-14);
        }
        let bare = Predictor::new(&v, &fp, &m, dt);
        assert_eq!(bare.force_at(1), f[1]);

        // without gravity m_p is not read (here it would be NaN) and the force is the same
        let nan = vec![f64::NAN; 2];
        let weightless = BodyForces {
            gravity: [0.0; 3],
            physical_mass: &nan,
            ..body
        };
        assert!(!weightless.weighs());
        let p = Predictor::new(&v, &fp, &m, dt).with_body_forces(Some(weightless), &x);
        let fd = weightless.damping_force(1, &x[1], &v[1], m[1]);
        let expect: Vec<u64> = (0..3)
            .map(|i| (f[1][i] + (0.0 + fd[i])).to_bits())
            .collect();
        assert_eq!(p.force_at(1).map(f64::to_bits).to_vec(), expect);
        // a negative zero is a gravity: m_p g is then −0, not +0
        assert!(BodyForces {
            gravity: [0.0, -0.0, 0.0],
            ..body
        }
        .weighs());
    }
}
