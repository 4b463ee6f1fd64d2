//! The energy ledger. Every joule is accounted for with the names of the reference
//! explicit solver (docs/THEORY.md §9):
//! ETOTAL = ALLKE + ALLIE + ALLVD + ALLFD − ALLWK, constant up to the balance error.
//!
//! Consistency with central differences: with x_n, v_{n±½} and M(v_{n+½}−v_{n−½})/Δt = f_n,
//! the quantity ½ v_{n−½}·M v_{n+½} + U(x_n) changes over a step by exactly
//! ½(f_n + f_{n+1})·(x_{n+1} − x_n) for linear internal forces. So kinetic energy is
//! evaluated as ½ v_{n−½}·M v_{n+½}, and the work of every other force is integrated by
//! the trapezoidal rule over each step: W += ½Δt (f_{n−1}·v_{n−½} + f_n·v_{n−½}).
//! A force category therefore needs only two power sums per step: f_n·v_{n−½} and
//! f_n·v_{n+½} (the latter is carried to the next step).

use serde::{Deserialize, Serialize};

/// Work done on the grains by one force category, integrated consistently with the
/// central-difference scheme (see module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct WorkAccumulator {
    /// ∫ f·v dt up to t_n (J).
    pub work: f64,
    /// ½Δt f_n·v_{n+½}, added at the next step (J).
    pub pending: f64,
}

impl WorkAccumulator {
    /// Adds the contribution of step n given the power sums f_n·v_{n−½} and f_n·v_{n+½} (W).
    #[inline]
    pub fn record(&mut self, dt: f64, power_before: f64, power_after: f64) {
        self.work += self.pending + 0.5 * dt * power_before;
        self.pending = 0.5 * dt * power_after;
    }
}

/// Energies of the whole model at the last completed step (J).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EnergyLedger {
    /// ALLKE: ½ v_{n−½}·M v_{n+½}.
    pub kinetic: f64,
    /// ALLSE: recoverable (elastic) strain energy Σ V0·ψ, a function of the current state.
    pub recoverable_strain: f64,
    /// ALLPD: plastic work Σ V0·T̃:Δεᵖ, accumulated over the run.
    pub plastic_dissipation: f64,
    /// ALLFD: frictional dissipation Σ f_t·Δslip.
    pub friction_dissipation: f64,
    /// Elastic energy stored in contact springs (penalty), if any.
    pub contact_energy: f64,
    /// Work of body forces (gravity) on the grains.
    pub body_force: WorkAccumulator,
    /// Work of prescribed motions, walls and applied loads (J), summed from their own
    /// accumulators each step.
    pub boundary_work: f64,
    /// Work of the damping forces (negative); ALLVD = −work.
    pub damping: WorkAccumulator,
    /// ETOTAL at the first step, for the relative balance error.
    pub initial_total: Option<f64>,
}

impl EnergyLedger {
    /// Number of additive values in [`EnergyLedger::to_sums`].
    pub const SUMS: usize = 11;

    /// The ledger as additive values (a rank's ledger covers its owned grains, so the
    /// model's is the sum over ranks of these, taken back with [`EnergyLedger::from_sums`]).
    pub fn to_sums(&self) -> [f64; Self::SUMS] {
        [
            self.kinetic,
            self.recoverable_strain,
            self.plastic_dissipation,
            self.friction_dissipation,
            self.contact_energy,
            self.body_force.work,
            self.body_force.pending,
            self.boundary_work,
            self.damping.work,
            self.damping.pending,
            self.initial_total.unwrap_or(0.0),
        ]
    }

    /// A ledger from summed [`EnergyLedger::to_sums`] values; `has_initial` says whether
    /// the first step's total has been taken.
    pub fn from_sums(v: &[f64; Self::SUMS], has_initial: bool) -> Self {
        EnergyLedger {
            kinetic: v[0],
            recoverable_strain: v[1],
            plastic_dissipation: v[2],
            friction_dissipation: v[3],
            contact_energy: v[4],
            body_force: WorkAccumulator {
                work: v[5],
                pending: v[6],
            },
            boundary_work: v[7],
            damping: WorkAccumulator {
                work: v[8],
                pending: v[9],
            },
            initial_total: has_initial.then_some(v[10]),
        }
    }

    /// The grains' whole stress work: ALLSE + ALLPD (equal to ALLSE for elastic grains).
    pub fn strain(&self) -> f64 {
        self.recoverable_strain + self.plastic_dissipation
    }

    /// ALLIE: internal energy = ALLSE + ALLPD + contact penalty energy.
    pub fn internal(&self) -> f64 {
        self.strain() + self.contact_energy
    }

    /// Plastic index ALLPD / (ALLSE + ALLPD) (0 before any strain energy): the share of the
    /// grains' stress work that plastic flow has dissipated.
    pub fn plastic_index(&self) -> f64 {
        ratio(self.plastic_dissipation, self.strain())
    }

    /// Friction index ALLFD / (ALLFD + ALLPD + ALLSE) (0 before any energy): the share of
    /// friction in the energy taken up by grains and contacts.
    pub fn friction_index(&self) -> f64 {
        ratio(
            self.friction_dissipation,
            self.friction_dissipation + self.strain(),
        )
    }

    /// ALLVD: energy removed by damping (J, ≥ 0 up to round-off).
    pub fn damping_dissipation(&self) -> f64 {
        -self.damping.work
    }

    /// ALLWK: external work = body forces + prescribed motions + walls (J).
    pub fn external_work(&self) -> f64 {
        self.body_force.work + self.boundary_work
    }

    /// ETOTAL = ALLKE + ALLIE + ALLVD + ALLFD − ALLWK (J).
    pub fn total(&self) -> f64 {
        self.kinetic + self.internal() + self.damping_dissipation() + self.friction_dissipation
            - self.external_work()
    }

    /// The largest of |ALLKE|, |ALLIE|, |ALLWK|, |ALLVD|, |ALLFD| (J): the scale of the
    /// balance error.
    pub fn largest_term(&self) -> f64 {
        self.kinetic
            .abs()
            .max(self.internal().abs())
            .max(self.external_work().abs())
            .max(self.damping_dissipation().abs())
            .max(self.friction_dissipation.abs())
    }

    /// Drift of ETOTAL since the first step, relative to the largest energy in play.
    pub fn relative_balance_error(&self) -> f64 {
        let e0 = self.initial_total.unwrap_or(0.0);
        let scale = self.largest_term().max(e0.abs());
        if scale == 0.0 {
            0.0
        } else {
            (self.total() - e0).abs() / scale
        }
    }
}

/// a / b, or 0 when b is not positive.
fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A single linear spring–mass oscillator integrated by central differences keeps
    /// ½v₋Mv₊ + U exactly; the ledger's balance must stay at round-off, including the
    /// work of a constant external force.
    #[test]
    fn ledger_balances_a_forced_oscillator() {
        let (m, k, f_ext, dt) = (2.0, 50.0, 3.0, 0.01);
        let (mut x, mut v) = (0.1, 0.0);
        let mut ledger = EnergyLedger::default();
        for _ in 0..20000 {
            let f = -k * x + f_ext;
            let v_new = v + dt * f / m;
            ledger.kinetic = 0.5 * m * v * v_new;
            ledger.recoverable_strain = 0.5 * k * x * x;
            ledger.body_force.record(dt, f_ext * v, f_ext * v_new);
            if ledger.initial_total.is_none() {
                ledger.initial_total = Some(ledger.total());
            }
            x += dt * v_new;
            v = v_new;
        }
        assert!(
            ledger.relative_balance_error() < 1e-10,
            "{}",
            ledger.relative_balance_error()
        );
        assert!(ledger.external_work().abs() > 1e-3);
    }
}
