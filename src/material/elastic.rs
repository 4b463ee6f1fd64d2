//! Elastic laws: each a small stateless type with its formula in the doc comment. All are
//! hyperelastic (P = ∂W/∂F) and objective for rotations of any size.

use super::ElasticParameters;
use crate::lanes::{build, dot3, Lanes};
use crate::math::{det3, mat_mul, mat_mul_fused};

/// An elastic law without state, P = ∂W/∂F: what the force kernel is compiled for once per
/// law (no per-element dispatch).
pub trait HyperelasticLaw: Copy + Send + Sync {
    /// Whether [`Self::first_piola_and_energy_lanes`] computes all lanes in one pass (the
    /// kernel then evaluates four elements at a time).
    const VECTORISES: bool;

    /// P (row-major 3×3, Pa) and W (J/m³) for a deformation gradient F (row-major 3×3).
    fn first_piola_and_energy(&self, f: &[f64; 9]) -> ([f64; 9], f64);

    /// The same for one element per lane, each lane bitwise equal to
    /// [`Self::first_piola_and_energy`]. The default evaluates the lanes one by one.
    #[inline(always)]
    fn first_piola_and_energy_lanes<T: Lanes>(&self, f: &[T; 9]) -> ([T; 9], T) {
        let f: [T::Array; 9] = build(T::Array::default(), |k| f[k].to_array());
        let mut p = [T::Array::default(); 9];
        let mut w = T::Array::default();
        for l in 0..T::WIDTH {
            let (pl, wl) = self.first_piola_and_energy(&build(0.0, |k| f[k][l]));
            for (out, v) in p.iter_mut().zip(pl) {
                out[l] = v;
            }
            w[l] = wl;
        }
        (
            build(T::splat(0.0), |k| T::from_array(p[k])),
            T::from_array(w),
        )
    }
}

macro_rules! hyperelastic_law_over_lanes {
    ($($law:ty),*) => {$(
        impl HyperelasticLaw for $law {
            const VECTORISES: bool = true;
            #[inline(always)]
            fn first_piola_and_energy(&self, f: &[f64; 9]) -> ([f64; 9], f64) {
                <$law>::first_piola_and_energy_lanes(self, f)
            }
            #[inline(always)]
            fn first_piola_and_energy_lanes<T: Lanes>(&self, f: &[T; 9]) -> ([T; 9], T) {
                <$law>::first_piola_and_energy_lanes(self, f)
            }
        }
    )*};
}
hyperelastic_law_over_lanes!(StVenantKirchhoff, SecondOrderBiot);

impl HyperelasticLaw for CorotationalLinear {
    // a Newton iteration per element: lanes would diverge, so it stays scalar
    const VECTORISES: bool = false;
    #[inline(always)]
    fn first_piola_and_energy(&self, f: &[f64; 9]) -> ([f64; 9], f64) {
        CorotationalLinear::first_piola_and_energy(self, f)
    }
}

/// St Venant–Kirchhoff hyperelasticity, the large-rotation form of linear isotropic
/// elasticity used for every elastic grain:
///
/// E = ½(FᵀF − I),  S = λ tr(E) I + 2μ E,  P = F S,  W = ½λ (tr E)² + μ E:E.
///
/// W depends on F only through FᵀF, so a rigid rotation (F = R) gives exactly zero
/// stress and energy: the formulation is objective for arbitrarily large rotations, which
/// rolling grains need. For the small strains of elastic grains (< 1e-2) it coincides with
/// Hooke's law to O(ε²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StVenantKirchhoff {
    /// First Lamé constant λ (Pa).
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
}

impl StVenantKirchhoff {
    pub fn new(p: &ElasticParameters) -> Self {
        let (lambda, mu) = p.lame();
        Self { lambda, mu }
    }

    /// Returns the first Piola–Kirchhoff stress P (row-major 3×3, Pa) and the strain energy
    /// density W (J/m³) for a deformation gradient F (row-major 3×3).
    #[inline(always)]
    pub fn first_piola_and_energy(&self, f: &[f64; 9]) -> ([f64; 9], f64) {
        self.first_piola_and_energy_lanes(f)
    }

    /// [`Self::first_piola_and_energy`] over lanes (one element per lane).
    #[inline(always)]
    pub fn first_piola_and_energy_lanes<T: Lanes>(&self, f: &[T; 9]) -> ([T; 9], T) {
        let e = green_lagrange_strain(f);
        let s = self.second_piola(&e);
        let tr = e[0] + e[4] + e[8];
        let mut ee = e[0] * e[0];
        for v in &e[1..] {
            ee = v.mul_add(*v, ee);
        }
        let w = T::splat(self.mu).mul_add(ee, T::splat(0.5 * self.lambda) * tr * tr);
        (mat_mul_fused(f, &s), w)
    }

    /// S = λ tr(E) I + 2μ E (Pa).
    #[inline(always)]
    pub fn second_piola<T: Lanes>(&self, e: &[T; 9]) -> [T; 9] {
        let tr = e[0] + e[4] + e[8];
        let two_mu = T::splat(2.0 * self.mu);
        let lambda_tr = T::splat(self.lambda) * tr;
        let mut s = build(T::splat(0.0), |k| two_mu * e[k]);
        s[0] = two_mu.mul_add(e[0], lambda_tr);
        s[4] = two_mu.mul_add(e[4], lambda_tr);
        s[8] = two_mu.mul_add(e[8], lambda_tr);
        s
    }
}

/// A symmetric 3×3 tensor stored as (xx, yy, zz, yz, xz, xy).
pub type Sym<T = f64> = [T; 6];

/// The default elastic law: linear isotropic elasticity in the Biot strain, with the stretch
/// taken to second order in the Green–Lagrange strain E = ½(FᵀF − I):
///
/// ε̃ = E − ½E² (= U − I + O(|E|³), U the right stretch),  T̃ = λ tr(ε̃) I + 2μ ε̃,
/// W = ½λ (tr ε̃)² + μ ε̃:ε̃,  S = ∂W/∂E = T̃ − ½(E T̃ + T̃ E) = T̃ (I − E),  P = F S.
///
/// The last form holds because ε̃, and so T̃, is a polynomial in E: T̃ and E commute, and
/// their product is symmetric. It costs one symmetric product where the anticommutator
/// costs two (the J2 law, whose elastic strain ε̃ − εᵖ does not commute with E, needs
/// the anticommutator).
///
/// W depends on F only through FᵀF, so it is exactly objective (a rigid rotation gives
/// zero stress, and rotating a strained element rotates its stress) without a polar
/// decomposition, and P is exactly the gradient of W (energy-consistent). Against the exact
/// Biot law (stress linear in U − I, [`CorotationalLinear`]) its stress differs by a
/// relative 2ε² (0.02 % at 1 % strain, 0.5 % at the 5 % of a 50 N glass contact peak),
/// where St Venant–Kirchhoff differs by 1.5ε. It costs one symmetric square and one
/// symmetric product more than St Venant–Kirchhoff and keeps no per-element state.
/// The J2 law ([`crate::material::j2`]) splits ε̃ additively.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SecondOrderBiot {
    /// First Lamé constant λ (Pa).
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
}

impl SecondOrderBiot {
    pub fn new(p: &ElasticParameters) -> Self {
        let (lambda, mu) = p.lame();
        Self { lambda, mu }
    }

    /// P (row-major, Pa) and W (J/m³) for a deformation gradient F.
    #[inline(always)]
    pub fn first_piola_and_energy(&self, f: &[f64; 9]) -> ([f64; 9], f64) {
        self.first_piola_and_energy_lanes(f)
    }

    /// [`Self::first_piola_and_energy`] over lanes (one element per lane).
    #[inline(always)]
    pub fn first_piola_and_energy_lanes<T: Lanes>(&self, f: &[T; 9]) -> ([T; 9], T) {
        let e = green_lagrange_sym(f);
        let (t, w) = hooke(self.lambda, self.mu, &biot_strain_from_green(&e));
        (
            first_piola_from_second_piola(f, &commuting_biot_stress(&e, &t)),
            w,
        )
    }
}

/// S = T̃ (I − E) of a stress T̃ that commutes with E (a polynomial in E): each entry
/// T̃ᵢⱼ − Σₖ T̃ᵢₖ Eₖⱼ by three fused negated multiply–adds.
#[inline(always)]
fn commuting_biot_stress<T: Lanes>(e: &Sym<T>, t: &Sym<T>) -> Sym<T> {
    let [e00, e11, e22, e12, e02, e01] = *e;
    let [t00, t11, t22, t12, t02, t01] = *t;
    [
        row_times_column_from(t00, [t00, t01, t02], [e00, e01, e02]),
        row_times_column_from(t11, [t01, t11, t12], [e01, e11, e12]),
        row_times_column_from(t22, [t02, t12, t22], [e02, e12, e22]),
        row_times_column_from(t12, [t01, t11, t12], [e02, e12, e22]),
        row_times_column_from(t02, [t00, t01, t02], [e02, e12, e22]),
        row_times_column_from(t01, [t00, t01, t02], [e01, e11, e12]),
    ]
}

/// `start` − row · column, one rounding per term (a function, not a closure: one the
/// compiler left uninlined would be compiled without the vector kernel's instructions).
#[inline(always)]
fn row_times_column_from<T: Lanes>(start: T, row: [T; 3], column: [T; 3]) -> T {
    let first = row[0].neg_mul_add(column[0], start);
    row[2].neg_mul_add(column[2], row[1].neg_mul_add(column[1], first))
}

/// Green–Lagrange strain E = ½(FᵀF − I) of a row-major F, as [`Sym`]. A diagonal entry is
/// ½c − ½ in one fused operation: bitwise ½ fl(c − 1), as halving commutes with rounding.
#[inline(always)]
pub fn green_lagrange_sym<T: Lanes>(f: &[T; 9]) -> Sym<T> {
    let c = |i: usize, j: usize| dot3(f[i], f[j], f[3 + i], f[3 + j], f[6 + i], f[6 + j]);
    let half = T::splat(0.5);
    let diagonal = |i: usize| c(i, i).mul_add(half, T::splat(-0.5));
    [
        diagonal(0),
        diagonal(1),
        diagonal(2),
        half * c(1, 2),
        half * c(0, 2),
        half * c(0, 1),
    ]
}

/// ε̃ = E − ½E², the Biot strain U − I to second order in E.
#[inline(always)]
pub fn biot_strain_from_green<T: Lanes>(e: &Sym<T>) -> Sym<T> {
    let e2 = sym_square(e);
    build(T::splat(0.0), |k| e2[k].mul_add(T::splat(-0.5), e[k]))
}

/// A² of a symmetric tensor: each entry one three-term sum.
#[inline(always)]
pub fn sym_square<T: Lanes>(a: &Sym<T>) -> Sym<T> {
    let [a00, a11, a22, a12, a02, a01] = *a;
    [
        dot3(a00, a00, a01, a01, a02, a02),
        dot3(a01, a01, a11, a11, a12, a12),
        dot3(a02, a02, a12, a12, a22, a22),
        dot3(a01, a02, a11, a12, a12, a22),
        dot3(a00, a02, a01, a12, a02, a22),
        dot3(a00, a01, a01, a11, a02, a12),
    ]
}

/// Isotropic Hooke law T = λ tr(ε) I + 2μ ε and its energy density ½λ(tr ε)² + μ ε:ε.
#[inline(always)]
pub fn hooke<T: Lanes>(lambda: f64, mu: f64, eps: &Sym<T>) -> (Sym<T>, T) {
    let tr = eps[0] + eps[1] + eps[2];
    let two_mu = T::splat(2.0 * mu);
    let lambda_tr = T::splat(lambda) * tr;
    let mut t = build(T::splat(0.0), |k| two_mu * eps[k]);
    for (v, e) in t.iter_mut().zip(eps).take(3) {
        *v = two_mu.mul_add(*e, lambda_tr);
    }
    let w = T::splat(mu).mul_add(sym_contract(eps, eps), T::splat(0.5 * lambda) * tr * tr);
    (t, w)
}

/// P = F·S with S = T̃ − ½(E T̃ + T̃ E): the first Piola–Kirchhoff stress of a stress T̃
/// work-conjugate to ε̃ = E − ½E² (dε̃ = dE − ½(E dE + dE E)).
#[inline(always)]
pub fn first_piola_from_biot_stress<T: Lanes>(f: &[T; 9], e: &Sym<T>, t: &Sym<T>) -> [T; 9] {
    first_piola_from_second_piola(f, &anticommutator_biot_stress(e, t))
}

/// S = T̃ − ½(E T̃ + T̃ E) of symmetric E and T̃ in fused chains: a diagonal entry is
/// T̃ᵢᵢ − Σₖ T̃ᵢₖ Eₖᵢ (the two products are equal), three operations; an off-diagonal one
/// T̃ᵢⱼ − ½ (its six-term sum), seven. 30 operations where two three-term sums, their sum
/// and the halving took 39.
#[inline(always)]
fn anticommutator_biot_stress<T: Lanes>(e: &Sym<T>, t: &Sym<T>) -> Sym<T> {
    let [e00, e11, e22, e12, e02, e01] = *e;
    let [t00, t11, t22, t12, t02, t01] = *t;
    let minus_half = T::splat(-0.5);
    [
        row_times_column_from(t00, [t00, t01, t02], [e00, e01, e02]),
        row_times_column_from(t11, [t01, t11, t12], [e01, e11, e12]),
        row_times_column_from(t22, [t02, t12, t22], [e02, e12, e22]),
        dot6(
            [e01, e11, e12, t01, t11, t12],
            [t02, t12, t22, e02, e12, e22],
        )
        .mul_add(minus_half, t12),
        dot6(
            [e00, e01, e02, t00, t01, t02],
            [t02, t12, t22, e02, e12, e22],
        )
        .mul_add(minus_half, t02),
        dot6(
            [e00, e01, e02, t00, t01, t02],
            [t01, t11, t12, e01, e11, e12],
        )
        .mul_add(minus_half, t01),
    ]
}

/// a · b of six terms in one chain of fused multiply–adds.
#[inline(always)]
fn dot6<T: Lanes>(a: [T; 6], b: [T; 6]) -> T {
    let mut sum = a[0] * b[0];
    for k in 1..6 {
        sum = a[k].mul_add(b[k], sum);
    }
    sum
}

/// P = F·S of a symmetric second Piola–Kirchhoff stress S.
#[inline(always)]
fn first_piola_from_second_piola<T: Lanes>(f: &[T; 9], s: &Sym<T>) -> [T; 9] {
    let mut p = [T::splat(0.0); 9];
    for i in 0..3 {
        let (a, b, c) = (f[3 * i], f[3 * i + 1], f[3 * i + 2]);
        p[3 * i] = dot3(a, s[0], b, s[5], c, s[4]);
        p[3 * i + 1] = dot3(a, s[5], b, s[1], c, s[3]);
        p[3 * i + 2] = dot3(a, s[4], b, s[3], c, s[2]);
    }
    p
}

/// A:B of two symmetric tensors.
#[inline(always)]
pub fn sym_contract<T: Lanes>(a: &Sym<T>, b: &Sym<T>) -> T {
    let shear = dot3(a[3], b[3], a[4], b[4], a[5], b[5]);
    T::splat(2.0).mul_add(shear, dot3(a[0], b[0], a[1], b[1], a[2], b[2]))
}

/// Corotational linear elasticity in Biot form: F = R·U (polar decomposition),
///
/// ε = U − I,  T = λ tr(ε) I + 2μ ε,  P = R·T,  W = ½λ (tr ε)² + μ ε:ε.
///
/// Like [`StVenantKirchhoff`] it is hyperelastic and exactly objective (W depends on U only),
/// but its stress is linear in the stretch, so it reproduces small-strain (Hooke) elasticity
/// to second order where SVK softens in compression by O(ε) (3.7 % in the force of a 50 N
/// glass contact). Use it to compare with linear-elastic references; it also gives the
/// rotated frame a J2 return mapping needs. T is coaxial with U, so P = R·T is exactly
/// ∂W/∂F.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorotationalLinear {
    /// First Lamé constant λ (Pa).
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
}

impl CorotationalLinear {
    pub fn new(p: &ElasticParameters) -> Self {
        let (lambda, mu) = p.lame();
        Self { lambda, mu }
    }

    /// P (row-major, Pa) and W (J/m³) for a deformation gradient F.
    #[inline(always)]
    pub fn first_piola_and_energy(&self, f: &[f64; 9]) -> ([f64; 9], f64) {
        let r = polar_rotation(f);
        // U = Rᵀ F, symmetrised against round-off
        let mut u = [0.0; 9];
        for i in 0..3 {
            for j in 0..3 {
                u[3 * i + j] = r[i] * f[j] + r[3 + i] * f[3 + j] + r[6 + i] * f[6 + j];
            }
        }
        let mut eps = [0.0; 9];
        for i in 0..3 {
            for j in 0..3 {
                eps[3 * i + j] =
                    0.5 * (u[3 * i + j] + u[3 * j + i]) - if i == j { 1.0 } else { 0.0 };
            }
        }
        let tr = eps[0] + eps[4] + eps[8];
        let mut t = [0.0; 9];
        for (ti, ei) in t.iter_mut().zip(&eps) {
            *ti = 2.0 * self.mu * ei;
        }
        t[0] += self.lambda * tr;
        t[4] += self.lambda * tr;
        t[8] += self.lambda * tr;
        let ee = eps.iter().map(|v| v * v).sum::<f64>();
        (mat_mul(&r, &t), 0.5 * self.lambda * tr * tr + self.mu * ee)
    }
}

/// Rotation R of the polar decomposition F = R U (det F > 0), by the scaled Newton
/// iteration X ← ½(ζX + ζ⁻¹X⁻ᵀ), ζ = |det X|^(−1/3). Its convergence depends only on the
/// stretch U (the iteration commutes with rotations): a few steps for the strains of
/// grains, quadratic to machine precision.
#[inline(always)]
pub fn polar_rotation(f: &[f64; 9]) -> [f64; 9] {
    let mut x = *f;
    for iteration in 0..12 {
        let det = det3(&x);
        if !(det.is_finite() && det.abs() > 0.0) {
            return x;
        }
        // scaling speeds up the first steps far from R; near R it is 1 to working precision
        let zeta = if iteration < 2 {
            1.0 / det.abs().cbrt()
        } else {
            1.0
        };
        // X⁻ᵀ = cof(X)/det
        let cof = [
            x[4] * x[8] - x[5] * x[7],
            x[5] * x[6] - x[3] * x[8],
            x[3] * x[7] - x[4] * x[6],
            x[2] * x[7] - x[1] * x[8],
            x[0] * x[8] - x[2] * x[6],
            x[1] * x[6] - x[0] * x[7],
            x[1] * x[5] - x[2] * x[4],
            x[2] * x[3] - x[0] * x[5],
            x[0] * x[4] - x[1] * x[3],
        ];
        let mut change: f64 = 0.0;
        for k in 0..9 {
            let next = 0.5 * (zeta * x[k] + cof[k] / (zeta * det));
            change = change.max((next - x[k]).abs());
            x[k] = next;
        }
        if change < 1e-14 {
            break;
        }
    }
    x
}

/// Green–Lagrange strain E = ½(FᵀF − I), row-major.
#[inline(always)]
pub fn green_lagrange_strain<T: Lanes>(f: &[T; 9]) -> [T; 9] {
    let mut e = [T::splat(0.0); 9];
    for i in 0..3 {
        for j in i..3 {
            let c = dot3(f[i], f[j], f[3 + i], f[3 + j], f[6 + i], f[6 + j]);
            let v = T::splat(0.5) * (c - T::splat(if i == j { 1.0 } else { 0.0 }));
            e[3 * i + j] = v;
            e[3 * j + i] = v;
        }
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Biot law's S = T̃(I − E) is the anticommutator form T̃ − ½(ET̃ + T̃E) (what the
    /// J2 law evaluates) to round-off, and its W is the plain formula's bit for bit, over
    /// strains from 10⁻⁹ to 10⁻¹, compression and shear, and materials nobody tuned for.
    #[test]
    fn biot_stress_by_one_product_is_the_anticommutator_form() {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut compared = 0;
        for (youngs, poisson) in [(63e9, 0.22), (2.1e11, 0.3), (3.0e6, 0.49), (1.0, 0.0)] {
            let p = ElasticParameters {
                youngs_modulus: youngs,
                poisson_ratio: poisson,
                density: 2500.0,
            };
            let law = SecondOrderBiot::new(&p);
            for exponent in -9..=-1 {
                for _ in 0..50 {
                    let size = 10f64.powi(exponent);
                    let mut f = [0.0; 9];
                    for (k, v) in f.iter_mut().enumerate() {
                        *v = size * uniform() + if k % 4 == 0 { 1.0 } else { 0.0 };
                    }
                    let e = green_lagrange_sym(&f);
                    let (t, w) = hooke(law.lambda, law.mu, &biot_strain_from_green(&e));
                    let anticommutator = first_piola_from_biot_stress(&f, &e, &t);
                    let (pk, w2) = law.first_piola_and_energy_lanes(&f);
                    // S differs by the rounding of products T̃ᵢₖEₖⱼ ≪ |T̃|: a few ulps of P
                    let scale = anticommutator.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    for (a, b) in anticommutator.iter().zip(pk) {
                        assert!((a - b).abs() <= 8.0 * f64::EPSILON * scale, "{f:?}");
                    }
                    assert_eq!(w.to_bits(), w2.to_bits(), "{f:?}");
                    compared += 1;
                }
            }
        }
        assert_eq!(compared, 4 * 9 * 50);
    }

    /// P = ∂W/∂F (central differences) for the Biot law at a rotated 2–3 % strain, for glass
    /// and for a nearly incompressible soft material.
    #[test]
    fn biot_stress_is_the_energy_gradient() {
        let (c, s) = (1.3f64.cos(), 1.3f64.sin());
        let rz = [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0];
        let f = mat_mul(
            &rz,
            &[1.02, 0.01, -0.03, 0.015, 0.98, 0.01, -0.02, 0.025, 1.03],
        );
        for (youngs, poisson) in [(63e9, 0.22), (3.0e6, 0.49)] {
            let p = ElasticParameters {
                youngs_modulus: youngs,
                poisson_ratio: poisson,
                density: 2500.0,
            };
            let law = SecondOrderBiot::new(&p);
            let (pk, _) = law.first_piola_and_energy(&f);
            let scale = pk.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let h = 1e-6;
            for k in 0..9 {
                let (mut fp, mut fm) = (f, f);
                fp[k] += h;
                fm[k] -= h;
                let energy = |f: &[f64; 9]| law.first_piola_and_energy(f).1;
                let dw = (energy(&fp) - energy(&fm)) / (2.0 * h);
                assert!(
                    (pk[k] - dw).abs() < 1e-7 * scale,
                    "E = {youngs}, component {k}: {} vs {dw}",
                    pk[k]
                );
            }
        }
    }

    #[test]
    fn rotation_gives_zero_stress_and_energy() {
        let p = ElasticParameters::paper_glass();
        let m = StVenantKirchhoff::new(&p);
        let (c, s) = (0.3_f64.cos(), 0.3_f64.sin());
        // rotation about an oblique axis: Rz(0.3)·Rx(1.1)
        let rz = [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0];
        let (c1, s1) = (1.1_f64.cos(), 1.1_f64.sin());
        let rx = [1.0, 0.0, 0.0, 0.0, c1, -s1, 0.0, s1, c1];
        let r = mat_mul(&rz, &rx);
        let (pk, w) = m.first_piola_and_energy(&r);
        assert!(pk.iter().all(|v| v.abs() < 1e-15 * p.youngs_modulus));
        assert!(w.abs() < 1e-20 * p.youngs_modulus);
    }

    #[test]
    fn small_uniaxial_strain_matches_hooke() {
        let p = ElasticParameters::paper_glass();
        let m = StVenantKirchhoff::new(&p);
        let eps = 1e-7;
        let f = [1.0 + eps, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let (pk, w) = m.first_piola_and_energy(&f);
        let (lambda, mu) = p.lame();
        let expected = (lambda + 2.0 * mu) * eps;
        assert!((pk[0] - expected).abs() < 1e-6 * expected);
        assert!((pk[4] - lambda * eps).abs() < 1e-6 * lambda * eps);
        let w_ref = 0.5 * (lambda + 2.0 * mu) * eps * eps;
        assert!((w - w_ref).abs() < 1e-6 * w_ref);
    }

    #[test]
    fn corotational_law_is_objective_matches_hooke_and_is_the_energy_gradient() {
        let p = ElasticParameters::paper_glass();
        let law = CorotationalLinear::new(&p);
        let (lambda, mu) = p.lame();
        // rigid rotation: zero stress
        let (c, s) = (1.3f64.cos(), 1.3f64.sin());
        let rz = [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0];
        let (pk, w) = law.first_piola_and_energy(&rz);
        assert!(
            pk.iter().all(|v| v.abs() < 1e-6) && w.abs() < 1e-12,
            "{pk:?}"
        );
        // 5 % uniaxial compression: exactly Hooke's stress (SVK would give 7 % less)
        let f = [0.95, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let (pk, _) = law.first_piola_and_energy(&f);
        let hooke = -(lambda + 2.0 * mu) * 0.05;
        assert!(
            (pk[0] - hooke).abs() < 1e-9 * hooke.abs(),
            "{} vs {hooke}",
            pk[0]
        );
        // rotated stretch: P = R·T with the same T
        let rf = mat_mul(&rz, &f);
        let (pr, _) = law.first_piola_and_energy(&rf);
        let expected = mat_mul(&rz, &pk);
        for k in 0..9 {
            assert!((pr[k] - expected[k]).abs() < 1e-6 * hooke.abs());
        }
        // P = ∂W/∂F at a general F
        let f = [1.01, 0.02, -0.03, 0.015, 0.98, 0.01, -0.02, 0.025, 1.03];
        let f = mat_mul(&rz, &f);
        let (pk, _) = law.first_piola_and_energy(&f);
        let h = 1e-7;
        for k in 0..9 {
            let (mut fp, mut fm) = (f, f);
            fp[k] += h;
            fm[k] -= h;
            let dw =
                (law.first_piola_and_energy(&fp).1 - law.first_piola_and_energy(&fm).1) / (2.0 * h);
            assert!(
                (pk[k] - dw).abs() < 1e-5 * p.youngs_modulus * 0.05,
                "component {k}: {} vs {dw}",
                pk[k]
            );
        }
        // polar rotation is orthonormal with det 1
        let r = polar_rotation(&f);
        assert!((det3(&r) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_symmetric_square_is_the_matrix_square() {
        let samples: [Sym; 3] = [
            [1e-3, -2e-4, 3.3e-5, 7e-4, -1.1e-3, 2.2e-4],
            [0.31, 1.0 / 3.0, -0.07, 0.0, 5e-9, -0.2],
            [-4.4e-6, 9.1e-7, 1.3e-6, -2.7e-7, 6.6e-7, 3.1e-6],
        ];
        for a in samples {
            let m = [a[0], a[5], a[4], a[5], a[1], a[3], a[4], a[3], a[2]];
            let full = mat_mul(&m, &m);
            let square = sym_square(&a);
            let size = sym_contract(&a, &a);
            for (k, (i, j)) in [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
                .into_iter()
                .enumerate()
            {
                assert!(
                    (square[k] - full[3 * i + j]).abs() <= 1e-15 * size,
                    "entry {k}: {} vs {}",
                    square[k],
                    full[3 * i + j]
                );
            }
        }
    }

    /// S = T̃ − ½(ET̃ + T̃E) by fused chains is the 3×3 matrix formula to round-off, for
    /// tensors that do not commute.
    #[test]
    fn anticommutator_stress_is_the_matrix_formula() {
        let full = |a: &Sym| [a[0], a[5], a[4], a[5], a[1], a[3], a[4], a[3], a[2]];
        let samples: [(Sym, Sym); 3] = [
            (
                [1e-3, -2e-4, 3.3e-5, 7e-4, -1.1e-3, 2.2e-4],
                [2.1e8, -3.0e7, 9.9e7, -4.4e7, 1.2e8, 6.0e6],
            ),
            (
                [0.31, 1.0 / 3.0, -0.07, 0.0, 5e-9, -0.2],
                [1.0, -2.0, 0.5, 0.25, -0.75, 3.0],
            ),
            (
                [-4.4e-6, 9.1e-7, 1.3e-6, -2.7e-7, 6.6e-7, 3.1e-6],
                [3.0e5, 1.0e5, -2.0e5, 7.0e4, -9.0e4, 4.0e4],
            ),
        ];
        for (e, t) in samples {
            let (em, tm) = (full(&e), full(&t));
            let (et, te) = (mat_mul(&em, &tm), mat_mul(&tm, &em));
            let s = anticommutator_biot_stress(&e, &t);
            let size = sym_contract(&t, &t).sqrt();
            for (k, (i, j)) in [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
                .into_iter()
                .enumerate()
            {
                let m = 3 * i + j;
                let expected = tm[m] - 0.5 * (et[m] + te[m]);
                assert!(
                    (s[k] - expected).abs() <= 4.0 * f64::EPSILON * size,
                    "entry {k}: {} vs {expected}",
                    s[k]
                );
            }
        }
    }

    #[test]
    fn wave_speeds_follow_formulas() {
        let p = ElasticParameters::paper_glass();
        let (lambda, mu) = p.lame();
        let cp = ((lambda + 2.0 * mu) / p.density).sqrt();
        assert!((p.dilatational_wave_speed() - cp).abs() < 1e-9 * cp);
        assert!((mu - p.youngs_modulus / (2.0 * (1.0 + p.poisson_ratio))).abs() < 1.0);
    }
}
