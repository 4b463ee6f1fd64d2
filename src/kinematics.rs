//! The velocity v_{n+½} while a step builds it.
//!
//! The central-difference predictor is v_{n+½} = v_{n−½} + Δt f/m; the boundary stage then
//! overwrites it where prescribed motions and walls act, and the integrator moves every
//! node with it. Stored for every node, the prediction is a pass over all nodes that
//! writes 24 bytes each and the integrator reads them back, which on the 2000-sphere block
//! was a tenth of the step outside the element kernel. A step whose force has no body or
//! damping term (an undamped shearing stage) therefore stores only the nodes that motions
//! and walls change, and every reader predicts the others where it reads them, from
//! exactly the same expression: the values are the same to the bit.

/// What a node's predicted v_{n+½} is computed from.
#[derive(Clone, Copy)]
pub struct Predictor<'a> {
    /// v_{n−½} (m/s).
    pub v: &'a [[f64; 3]],
    /// The node forces of the step, complete (N).
    pub force: &'a [[f64; 3]],
    /// The integrator's nodal masses (kg).
    pub mass: &'a [f64],
    /// Δt (s).
    pub dt: f64,
}

impl<'a> Predictor<'a> {
    pub fn new(v: &'a [[f64; 3]], force: &'a [[f64; 3]], mass: &'a [f64], dt: f64) -> Self {
        Self { v, force, mass, dt }
    }

    /// v_{n−½} + Δt f/m of node `n`.
    #[inline(always)]
    pub fn at(&self, n: usize) -> [f64; 3] {
        predict(self.v[n], self.force[n], self.mass[n], self.dt)
    }
}

/// v + Δt f/m, the one expression every path evaluates.
#[inline(always)]
pub fn predict(v: [f64; 3], f: [f64; 3], m: f64, dt: f64) -> [f64; 3] {
    [
        v[0] + dt * f[0] / m,
        v[1] + dt * f[1] / m,
        v[2] + dt * f[2] / m,
    ]
}

/// v_{n+½} of every node: stored where set, else the prediction (module docs).
#[derive(Debug, Default)]
pub struct NextVelocity {
    values: Vec<[f64; 3]>,
    /// Per node: `values` holds its v_{n+½} (when not `all_stored`).
    stored: Vec<bool>,
    /// The nodes marked in `stored`, to clear them for the next step.
    changed: Vec<u32>,
    all_stored: bool,
}

impl NextVelocity {
    pub fn new(nodes: usize) -> Self {
        Self {
            values: vec![[0.0; 3]; nodes],
            stored: vec![false; nodes],
            changed: Vec::new(),
            all_stored: false,
        }
    }

    /// Starts a step whose boundary stage writes every node's value: the returned slice.
    pub fn store_every_node(&mut self) -> &mut [[f64; 3]] {
        self.forget_stored();
        self.all_stored = true;
        &mut self.values
    }

    /// Starts a step whose nodes keep their prediction unless set.
    pub fn predict_where_read(&mut self) {
        self.forget_stored();
        self.all_stored = false;
    }

    fn forget_stored(&mut self) {
        for &n in &self.changed {
            self.stored[n as usize] = false;
        }
        self.changed.clear();
    }

    /// The stored v_{n+½} of node `n`, `None` where it is the prediction.
    #[inline(always)]
    pub fn stored(&self, n: usize) -> Option<[f64; 3]> {
        (self.all_stored || self.stored[n]).then(|| self.values[n])
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
        if !self.all_stored && !self.stored[n] {
            self.stored[n] = true;
            self.changed.push(n as u32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_is_its_prediction_until_set_and_again_next_step() {
        let (v, f, m) = (
            vec![[1.0, 2.0, 3.0]; 3],
            vec![[0.5, -1.0, 2.0]; 3],
            vec![2.0; 3],
        );
        let p = Predictor::new(&v, &f, &m, 0.1);
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
        next.store_every_node()[2] = [4.0; 3];
        assert_eq!(next.stored(2), Some([4.0; 3]));
    }
}
