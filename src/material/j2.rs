//! Von Mises (J2) plasticity with linear isotropic hardening, in the strain measure of the
//! default elastic law.
//!
//! Strain and stress: ε̃ = E − ½E² (E = ½(FᵀF − I); ε̃ is the Biot strain U − I to second
//! order) and its work-conjugate stress T̃ (see [`super::elastic::SecondOrderBiot`]). Both
//! live in the reference (unrotated) frame, so everything below is a function of FᵀF and
//! the stored plastic strain: the law is exactly objective — a grain turned rigidly by any
//! angle, in any number of increments, keeps T̃ and εᵖ to round-off, and its Cauchy stress
//! turns with it. No rotation is extracted or stored.
//!
//! Additive split ε̃ = ε̃ᵉ + εᵖ, T̃ = λ tr(ε̃ᵉ) I + 2μ ε̃ᵉ, yield function
//! f = q − (σy + H α) with q = √(3/2 s:s), s = dev T̃, α the equivalent plastic strain.
//! Return mapping (radial return, exact for linear hardening):
//!
//! Δα = ⟨f_trial⟩ / (3μ + H),  εᵖ += Δα · (3/2) s_trial / q_trial,
//! s = s_trial (1 − 3μ Δα / q_trial),  dissipation += T̃ : Δεᵖ = (σy + H α_{n+1}) Δα.
//!
//! Stored energy is ψ = ½λ (tr ε̃ᵉ)² + μ ε̃ᵉ:ε̃ᵉ (ALLSE); the plastic work T̃ : Δεᵖ is ALLPD
//! (as in the reference solver it includes the part locked in by hardening).

use super::elastic::{hooke, Sym};
use crate::lanes::{build, dot3, Lanes};
use serde::{Deserialize, Serialize};

/// Plastic state of one element (the only per-element material state in mufe).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[repr(C)]
pub struct PlasticPoint {
    /// Plastic strain εᵖ in the ε̃ measure (xx, yy, zz, yz, xz, xy; tensor components).
    pub strain: Sym,
    /// Equivalent plastic strain α = Σ Δα (–).
    pub equivalent: f64,
}

impl PlasticPoint {
    /// The states as records of seven f64: εᵖ (Sym order), then α; how the vector kernel
    /// loads eight of them into lanes.
    #[inline(always)]
    pub fn as_records(points: &[Self]) -> &[[f64; 7]] {
        // SAFETY: `PlasticPoint` is `repr(C)` of [f64; 6] and f64: seven f64, no padding
        unsafe { std::slice::from_raw_parts(points.as_ptr() as *const [f64; 7], points.len()) }
    }

    /// [`PlasticPoint::as_records`] for writing: how the vector kernel stores eight.
    #[inline(always)]
    pub fn as_records_mut(points: &mut [Self]) -> &mut [[f64; 7]] {
        // SAFETY: as `as_records`
        unsafe {
            std::slice::from_raw_parts_mut(points.as_mut_ptr() as *mut [f64; 7], points.len())
        }
    }
}

/// J2 parameters with the elastic constants they return against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct J2 {
    /// First Lamé constant λ (Pa).
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Initial yield stress σy (Pa).
    pub yield_stress: f64,
    /// Linear isotropic hardening modulus H = dσy/dα (Pa).
    pub hardening_modulus: f64,
}

/// Outcome of one return mapping.
#[derive(Debug, Clone, Copy)]
pub struct Return {
    /// T̃ after the return (Pa).
    pub stress: Sym,
    /// Elastic energy density ψ(ε̃ᵉ) (J/m³).
    pub stored_energy: f64,
    /// Plastic work density of this increment, T̃ : Δεᵖ (J/m³).
    pub dissipation: f64,
    /// The state after the increment.
    pub point: PlasticPoint,
}

impl J2 {
    /// Current yield stress σy + H α (Pa).
    pub fn flow_stress(&self, equivalent: f64) -> f64 {
        self.yield_stress + self.hardening_modulus * equivalent
    }

    /// Returns the stress at total strain `eps` (ε̃) from the state `old`, without changing
    /// it: the new state is in the result. A pure function, so output and diagnostics can
    /// call it with the committed state and get what the step computed.
    #[inline(always)]
    pub fn return_map(&self, eps: &Sym, old: &PlasticPoint) -> Return {
        let r = self.return_map_lanes(eps, &old.strain, old.equivalent);
        Return {
            stress: r.stress,
            stored_energy: r.stored_energy,
            dissipation: r.dissipation,
            point: PlasticPoint {
                strain: r.strain,
                equivalent: r.equivalent,
            },
        }
    }

    /// [`Self::return_map`] for one element per lane (state split into εᵖ and α), each
    /// lane bitwise equal to it. Both branches are computed and the plastic one kept where
    /// the trial stress exceeds the flow stress, so the elastic lanes return the trial
    /// values and the old state exactly.
    #[inline(always)]
    pub fn return_map_lanes<T: Lanes>(
        &self,
        eps: &Sym<T>,
        old_strain: &Sym<T>,
        old_equivalent: T,
    ) -> ReturnLanes<T> {
        let elastic: Sym<T> = build(T::splat(0.0), |k| eps[k] - old_strain[k]);
        let (trial, trial_energy) = hooke(self.lambda, self.mu, &elastic);
        // products by constants, not divisions: a division costs the eight-lane kernel
        // several multiplies' worth of time
        let mean = (trial[0] + trial[1] + trial[2]) * T::splat(1.0 / 3.0);
        let dev = [
            trial[0] - mean,
            trial[1] - mean,
            trial[2] - mean,
            trial[3],
            trial[4],
            trial[5],
        ];
        let shear = dot3(dev[3], dev[3], dev[4], dev[4], dev[5], dev[5]);
        let ss = T::splat(2.0).mul_add(shear, dot3(dev[0], dev[0], dev[1], dev[1], dev[2], dev[2]));
        let q = (T::splat(1.5) * ss).sqrt();
        let flow_stress =
            |alpha: T| T::splat(self.hardening_modulus).mul_add(alpha, T::splat(self.yield_stress));
        let excess = q - flow_stress(old_equivalent);
        if (-excess).all_positive() {
            // every lane elastic (the common group): what the picks below would give, bit
            // for bit, without the plastic branch's division and second energy
            return ReturnLanes {
                stress: trial,
                stored_energy: trial_energy,
                dissipation: T::splat(0.0),
                strain: *old_strain,
                equivalent: old_equivalent,
                excess,
            };
        }
        // the plastic branch (its values are discarded where `excess` ≤ 0)
        let d_alpha = excess * T::splat(1.0 / (3.0 * self.mu + self.hardening_modulus));
        let per_q = d_alpha / q;
        let flow = T::splat(1.5) * per_q;
        let shrink = T::splat(-3.0 * self.mu).mul_add(per_q, T::splat(1.0));
        let mut strain = *old_strain;
        let mut returned_elastic = elastic;
        let mut stress: Sym<T> = [T::splat(0.0); 6];
        for k in 0..6 {
            strain[k] = flow.mul_add(dev[k], strain[k]);
            returned_elastic[k] = (-flow).mul_add(dev[k], returned_elastic[k]);
            stress[k] = shrink * dev[k];
        }
        for v in stress.iter_mut().take(3) {
            *v = *v + mean;
        }
        let equivalent = old_equivalent + d_alpha;
        // ψ of the returned elastic strain: the volumetric part is unchanged
        let (_, stored_energy) = hooke(self.lambda, self.mu, &returned_elastic);
        let dissipation = flow_stress(equivalent) * d_alpha;
        let pick = |plastic: T, elastic: T| excess.where_positive(plastic, elastic);
        ReturnLanes {
            stress: build(T::splat(0.0), |k| pick(stress[k], trial[k])),
            stored_energy: pick(stored_energy, trial_energy),
            dissipation: pick(dissipation, T::splat(0.0)),
            strain: build(T::splat(0.0), |k| pick(strain[k], old_strain[k])),
            equivalent: pick(equivalent, old_equivalent),
            excess,
        }
    }
}

/// [`Return`] of one element per lane, the state split into εᵖ and α.
#[derive(Debug, Clone, Copy)]
pub struct ReturnLanes<T> {
    pub stress: Sym<T>,
    pub stored_energy: T,
    pub dissipation: T,
    pub strain: Sym<T>,
    pub equivalent: T,
    /// q − (σy + Hα) of the trial stress: > 0 where the lane took the plastic branch; the
    /// other lanes returned their old state exactly.
    pub excess: T,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::elastic::sym_contract;
    use crate::material::ElasticParameters;

    fn steel_like() -> J2 {
        let p = ElasticParameters {
            youngs_modulus: 2.1e11,
            poisson_ratio: 0.3,
            density: 7850.0,
        };
        let (lambda, mu) = p.lame();
        J2 {
            lambda,
            mu,
            yield_stress: 2.5e8,
            hardening_modulus: 2.0e9,
        }
    }

    fn von_mises(t: &Sym) -> f64 {
        let m = (t[0] + t[1] + t[2]) / 3.0;
        let d = [t[0] - m, t[1] - m, t[2] - m, t[3], t[4], t[5]];
        (1.5 * sym_contract(&d, &d)).sqrt()
    }

    #[test]
    fn returned_stress_is_on_the_hardened_yield_surface_and_dissipation_is_t_dot_depsp() {
        let law = steel_like();
        let eps = [3e-3, -1e-3, 0.5e-3, 1e-3, -2e-3, 0.7e-3];
        let r = law.return_map(&eps, &PlasticPoint::default());
        assert!(r.point.equivalent > 0.0);
        let q = von_mises(&r.stress);
        let flow = law.flow_stress(r.point.equivalent);
        assert!((q - flow).abs() < 1e-12 * flow, "{q} vs {flow}");
        // plastic flow is deviatoric and T̃ : Δεᵖ is the recorded dissipation
        let dp = r.point.strain;
        assert!((dp[0] + dp[1] + dp[2]).abs() < 1e-18);
        let work = sym_contract(&r.stress, &dp);
        assert!((work - r.dissipation).abs() < 1e-9 * r.dissipation);
        // Δα = √(2/3 Δεᵖ:Δεᵖ)
        let alpha = (2.0 / 3.0 * sym_contract(&dp, &dp)).sqrt();
        assert!((alpha - r.point.equivalent).abs() < 1e-12 * alpha);
        // returning again from the new state at the same strain changes nothing
        let again = law.return_map(&eps, &r.point);
        assert!(again.dissipation <= 1e-12 * r.dissipation);
        assert!((again.point.equivalent - r.point.equivalent).abs() < 1e-15);
    }

    #[test]
    fn below_yield_the_law_is_hooke() {
        let law = steel_like();
        let eps = [1e-4, -2e-5, 0.0, 1e-5, 0.0, 0.0];
        let r = law.return_map(&eps, &PlasticPoint::default());
        let (t, w) = hooke(law.lambda, law.mu, &eps);
        assert_eq!(r.stress, t);
        assert_eq!(r.stored_energy, w);
        assert_eq!(r.dissipation, 0.0);
    }
}
