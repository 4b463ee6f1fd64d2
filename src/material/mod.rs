//! Grain materials: small stateless types with a `Parameters` type and the formula in the
//! doc comment ([`elastic`], [`j2`]). The only per-element state is the plastic state of
//! elements of plastic materials ([`PlasticPoint`]); it lives in the run's `State`.

pub mod elastic;
pub mod j2;

pub use elastic::{
    green_lagrange_strain, polar_rotation, CorotationalLinear, HyperelasticLaw, SecondOrderBiot,
    StVenantKirchhoff,
};
pub use j2::{PlasticPoint, J2};

use crate::math::det3;
use serde::{Deserialize, Serialize};

/// Isotropic linear elasticity parameters (SI units).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElasticParameters {
    /// Young's modulus E (Pa).
    pub youngs_modulus: f64,
    /// Poisson's ratio ν (–), −1 < ν < 0.5.
    pub poisson_ratio: f64,
    /// Mass density ρ (kg/m³).
    pub density: f64,
}

impl ElasticParameters {
    /// The glass of the source paper (docs/THEORY.md, Conventions): E = 63 GPa, ν = 0.22,
    /// ρ = 2500 kg/m³ — the material of the validation references and the tests.
    pub const fn paper_glass() -> Self {
        Self {
            youngs_modulus: 63e9,
            poisson_ratio: 0.22,
            density: 2500.0,
        }
    }

    /// Lamé constants (λ, μ) in Pa: λ = Eν/((1+ν)(1−2ν)), μ = G = E/(2(1+ν)).
    pub fn lame(&self) -> (f64, f64) {
        let e = self.youngs_modulus;
        let nu = self.poisson_ratio;
        (
            e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            e / (2.0 * (1.0 + nu)),
        )
    }

    /// Shear modulus G = E/(2(1+ν)) (Pa).
    pub fn shear_modulus(&self) -> f64 {
        self.lame().1
    }

    /// Dilatational (P-wave) speed c_p = √((λ+2G)/ρ) (m/s).
    pub fn dilatational_wave_speed(&self) -> f64 {
        let (lambda, mu) = self.lame();
        ((lambda + 2.0 * mu) / self.density).sqrt()
    }

    /// Bar wave speed √(E/ρ) (m/s).
    pub fn bar_wave_speed(&self) -> f64 {
        (self.youngs_modulus / self.density).sqrt()
    }

    /// Plane-strain modulus of a pair of identical bodies for Hertz, E/(1−ν²) (Pa).
    pub fn plane_strain_modulus(&self) -> f64 {
        self.youngs_modulus / (1.0 - self.poisson_ratio * self.poisson_ratio)
    }
}

/// Which elastic law a material uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ElasticLawKind {
    /// [`SecondOrderBiot`]: Hooke's law in the Biot strain to second order (default; the
    /// strain measure of J2 plasticity).
    #[default]
    Biot,
    /// [`StVenantKirchhoff`]: S linear in the Green–Lagrange strain (softer than Hooke in
    /// compression by 1.5ε).
    StVenantKirchhoff,
    /// [`CorotationalLinear`]: Biot stress exactly linear in U − I (polar decomposition by
    /// Newton iteration; ~4× the cost of the default).
    Corotational,
}

/// J2 parameters of a plastic material (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlasticParameters {
    /// Initial yield stress σy (Pa).
    pub yield_stress: f64,
    /// Linear isotropic hardening modulus H (Pa), σ_flow = σy + H α.
    pub hardening_modulus: f64,
}

/// A material's law with its constants, dispatched per element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialLaw {
    pub kind: ElasticLawKind,
    /// First Lamé constant λ (Pa).
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// J2 plasticity on top of the [`ElasticLawKind::Biot`] law, for plastic materials.
    pub plastic: Option<J2>,
}

/// Stress response of one element.
#[derive(Debug, Clone, Copy)]
pub struct Response {
    /// First Piola–Kirchhoff stress P (row-major, Pa).
    pub first_piola: [f64; 9],
    /// Recoverable (elastic) energy density (J/m³).
    pub stored_energy: f64,
    /// Plastic work density of this evaluation (J/m³).
    pub dissipation: f64,
    /// Plastic state after the evaluation (plastic materials only).
    pub point: Option<PlasticPoint>,
}

impl MaterialLaw {
    /// Plasticity requires the Biot law (its strain measure); the scene checks enforce it.
    pub fn new(
        p: &ElasticParameters,
        kind: ElasticLawKind,
        plastic: Option<PlasticParameters>,
    ) -> Self {
        let (lambda, mu) = p.lame();
        Self {
            kind,
            lambda,
            mu,
            plastic: plastic.map(|q| J2 {
                lambda,
                mu,
                yield_stress: q.yield_stress,
                hardening_modulus: q.hardening_modulus,
            }),
        }
    }

    /// P (row-major, Pa) and the elastic energy density W (J/m³) of an elastic law.
    #[inline(always)]
    pub fn first_piola_and_energy(&self, f: &[f64; 9]) -> ([f64; 9], f64) {
        let (lambda, mu) = (self.lambda, self.mu);
        match self.kind {
            ElasticLawKind::Biot => SecondOrderBiot { lambda, mu }.first_piola_and_energy(f),
            ElasticLawKind::StVenantKirchhoff => {
                StVenantKirchhoff { lambda, mu }.first_piola_and_energy(f)
            }
            ElasticLawKind::Corotational => {
                CorotationalLinear { lambda, mu }.first_piola_and_energy(f)
            }
        }
    }

    /// The response at F from the committed plastic state `point` (ignored by elastic
    /// laws). Pure: the caller commits `Response::point`.
    #[inline(always)]
    pub fn respond(&self, f: &[f64; 9], point: Option<&PlasticPoint>) -> Response {
        match (&self.plastic, point) {
            (Some(j2), Some(old)) => {
                let e = elastic::green_lagrange_sym(f);
                let eps = elastic::biot_strain_from_green(&e);
                let r = j2.return_map(&eps, old);
                Response {
                    first_piola: elastic::first_piola_from_biot_stress(f, &e, &r.stress),
                    stored_energy: r.stored_energy,
                    dissipation: r.dissipation,
                    point: Some(r.point),
                }
            }
            _ => {
                let (first_piola, stored_energy) = self.first_piola_and_energy(f);
                Response {
                    first_piola,
                    stored_energy,
                    dissipation: 0.0,
                    point: None,
                }
            }
        }
    }
}

/// Cauchy stress σ = J⁻¹ P Fᵀ (Pa), row-major, for output.
pub fn cauchy_from_first_piola(p: &[f64; 9], f: &[f64; 9]) -> [f64; 9] {
    let j = det3(f);
    let mut sigma = [0.0; 9];
    for i in 0..3 {
        for k in 0..3 {
            sigma[3 * i + k] =
                (p[3 * i] * f[3 * k] + p[3 * i + 1] * f[3 * k + 1] + p[3 * i + 2] * f[3 * k + 2])
                    / j;
        }
    }
    sigma
}

/// von Mises equivalent of a symmetric stress (Pa).
pub fn von_mises(s: &[f64; 9]) -> f64 {
    let tr = (s[0] + s[4] + s[8]) / 3.0;
    let mut j2 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let d = s[3 * i + j] - if i == j { tr } else { 0.0 };
            j2 += d * d;
        }
    }
    (1.5 * j2).sqrt()
}
