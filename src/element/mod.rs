//! Linear tetrahedron (tet4) kinematics in the total-Lagrangian form.
//!
//! Why total Lagrangian: F = Ds·Dm⁻¹ is computed from current positions, and the default
//! laws (see [`crate::material`]) depend on F only through FᵀF, so a rigid rotation of any
//! size gives exactly zero stress — no corotational frame to extract, no rate integration
//! that could drift. Dm⁻¹ and the reference volume are the only per-element data the force
//! kernel needs (80 bytes), plus the plastic state of elements of plastic materials.

use crate::lanes::{build, dot3, Lanes, TetNodes};
use crate::material::elastic::{
    biot_strain_from_green, first_piola_from_biot_stress, green_lagrange_sym, Sym,
};
use crate::material::{HyperelasticLaw, MaterialLaw, PlasticPoint, J2};
use crate::math::{det3, det3_fused};

pub mod references;
pub use references::{ReferenceBlock, TetReferences};

/// Reference data of one tetrahedron needed by the force kernel.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[repr(C)]
pub struct TetReference {
    /// Inverse of the reference edge matrix Dm = [X1−X0, X2−X0, X3−X0] (row-major, 1/m).
    pub dm_inv: [f64; 9],
    /// Reference volume V0 (m³).
    pub volume: f64,
}

impl TetReference {
    /// Returns `None` if the tetrahedron is inverted or degenerate (V0 ≤ 0).
    pub fn new(x: [[f64; 3]; 4]) -> Option<Self> {
        let dm = edge_matrix(&x);
        let det = det3(&dm);
        if det.is_nan() || det <= 0.0 {
            return None;
        }
        Some(Self {
            dm_inv: inverse3(&dm, det),
            volume: det / 6.0,
        })
    }

    /// Shape-function gradients ∇N_a (1/m) of the four nodes in the reference frame.
    pub fn shape_gradients(&self) -> [[f64; 3]; 4] {
        // ∇N_{1,2,3} are the rows of Dm⁻¹; ∇N_0 = −Σ.
        let d = &self.dm_inv;
        let g1 = [d[0], d[1], d[2]];
        let g2 = [d[3], d[4], d[5]];
        let g3 = [d[6], d[7], d[8]];
        let g0 = [
            -(g1[0] + g2[0] + g3[0]),
            -(g1[1] + g2[1] + g3[1]),
            -(g1[2] + g2[2] + g3[2]),
        ];
        [g0, g1, g2, g3]
    }
}

/// Edge matrix [x1−x0, x2−x0, x3−x0] as columns, row-major.
#[inline(always)]
pub fn edge_matrix<T: Lanes>(x: &[[T; 3]; 4]) -> [T; 9] {
    let mut m = [T::splat(0.0); 9];
    for c in 0..3 {
        for r in 0..3 {
            m[3 * r + c] = x[c + 1][r] - x[0][r];
        }
    }
    m
}

/// Inverse of a row-major 3×3 matrix with known determinant.
#[inline(always)]
pub fn inverse3(m: &[f64; 9], det: f64) -> [f64; 9] {
    let inv_det = 1.0 / det;
    [
        (m[4] * m[8] - m[5] * m[7]) * inv_det,
        (m[2] * m[7] - m[1] * m[8]) * inv_det,
        (m[1] * m[5] - m[2] * m[4]) * inv_det,
        (m[5] * m[6] - m[3] * m[8]) * inv_det,
        (m[0] * m[8] - m[2] * m[6]) * inv_det,
        (m[2] * m[3] - m[0] * m[5]) * inv_det,
        (m[3] * m[7] - m[4] * m[6]) * inv_det,
        (m[1] * m[6] - m[0] * m[7]) * inv_det,
        (m[0] * m[4] - m[1] * m[3]) * inv_det,
    ]
}

/// Deformation gradient F = Ds·Dm⁻¹ of a tetrahedron at current node positions.
#[inline(always)]
pub fn deformation_gradient(x: &[[f64; 3]; 4], dm_inv: &[f64; 9]) -> [f64; 9] {
    let ds = edge_matrix(x);
    crate::math::mat_mul_fused(&ds, dm_inv)
}

/// Outcome of one element force evaluation.
#[derive(Debug, Clone, Copy)]
pub struct ElementForces {
    /// Forces on the four nodes from the element's stress (N): f_a = −V0 P ∇N_a.
    pub nodal: [[f64; 3]; 4],
    /// Recoverable strain energy V0·W (J).
    pub strain_energy: f64,
    /// Plastic work of this evaluation V0·T̃:Δεᵖ (J).
    pub plastic_work: f64,
    /// det F (–): ≤ 0 means the element inverted.
    pub jacobian: f64,
    /// Plastic state after the evaluation (elements of plastic materials).
    pub point: Option<PlasticPoint>,
}

/// Nodal forces of one tetrahedron: f_{1,2,3} = columns of H = −V0 P Dm⁻ᵀ, f_0 = −Σ.
/// `point` is the committed plastic state (plastic materials); the state after this
/// evaluation is returned, not written.
#[inline(always)]
pub fn tet_forces(
    x: &[[f64; 3]; 4],
    reference: &TetReference,
    material: &MaterialLaw,
    point: Option<&PlasticPoint>,
) -> ElementForces {
    let f = deformation_gradient(x, &reference.dm_inv);
    let response = material.respond(&f, point);
    ElementForces {
        nodal: nodal_forces(&response.first_piola, &reference.dm_inv, reference.volume),
        strain_energy: reference.volume * response.stored_energy,
        plastic_work: reference.volume * response.dissipation,
        jacobian: det3_fused(&f),
        point: response.point,
    }
}

/// [`tet_forces`] of an elastic law, compiled for that law: (nodal forces (N), strain
/// energy V0·W (J), det F).
#[inline(always)]
pub fn tet_forces_elastic<L: HyperelasticLaw>(
    x: &[[f64; 3]; 4],
    reference: &TetReference,
    law: &L,
) -> ([[f64; 3]; 4], f64, f64) {
    let f = deformation_gradient(x, &reference.dm_inv);
    let (p, w) = law.first_piola_and_energy(&f);
    (
        nodal_forces(&p, &reference.dm_inv, reference.volume),
        reference.volume * w,
        det3_fused(&f),
    )
}

/// What an element evaluation over lanes gives, one element per lane of `T`.
#[derive(Debug, Clone, Copy)]
pub struct ElementLanes<T> {
    /// Forces on the four nodes (N), `nodal[a][i]`.
    pub nodal: [[T; 3]; 4],
    /// V0·W (J).
    pub strain_energy: T,
    /// V0·plastic work (J); zero for an elastic law.
    pub plastic_work: T,
    /// det F (–).
    pub jacobian: T,
}

/// [`tet_forces_elastic`] of elements `first..first + T::WIDTH` of `tets`, one per lane of
/// `T` and bitwise equal to it in each; their reference data are lanes `lane0..` of
/// `reference`.
#[inline(always)]
pub fn tet_forces_elastic_lanes<L: HyperelasticLaw, T: Lanes>(
    tets: &TetNodes,
    first: usize,
    reference: &ReferenceBlock,
    lane0: usize,
    law: &L,
) -> ElementLanes<T> {
    let (f, d, v) = deformation_lanes::<T>(tets, first, reference, lane0);
    let (p, w) = law.first_piola_and_energy_lanes(&f);
    ElementLanes {
        nodal: nodal_forces(&p, &d, v),
        strain_energy: v * w,
        plastic_work: T::splat(0.0),
        jacobian: det3_fused(&f),
    }
}

/// The return mapping of elements `first..first + T::WIDTH` of `tets`, of a J2 material,
/// one per lane of `T`, from their committed plastic states `old` (one per lane, from
/// `first`; the reference data are lanes `lane0..` of `reference`): what their forces need
/// ([`PlasticStress::forces`]) and their states after the step. Each lane is bitwise equal
/// to [`tet_forces`]. The forces are a separate call so that the caller can store the
/// states first: a state held across the force computation does not fit in AVX2's sixteen
/// registers and spills (docs/BENCHMARKS.md, session 44).
#[inline(always)]
pub fn plastic_return_lanes<T: Lanes>(
    tets: &TetNodes,
    first: usize,
    reference: &ReferenceBlock,
    lane0: usize,
    j2: &J2,
    old: &[PlasticPoint],
) -> (PlasticStress<T>, PlasticLanes<T>) {
    let (f, d, v) = deformation_lanes::<T>(tets, first, reference, lane0);
    let e = green_lagrange_sym(&f);
    let eps = biot_strain_from_green(&e);
    let old_record: [T; 7] = T::gather_records(PlasticPoint::as_records(&old[..T::WIDTH]));
    let mut old_strain = [T::splat(0.0); 6];
    old_strain.copy_from_slice(&old_record[..6]);
    let old_equivalent = old_record[6];
    let r = j2.return_map_lanes(&eps, &old_strain, old_equivalent);
    let stress = PlasticStress {
        f,
        d,
        v,
        e,
        stress: r.stress,
        stored_energy: r.stored_energy,
        dissipation: r.dissipation,
    };
    let state = PlasticLanes {
        strain: r.strain,
        equivalent: r.equivalent,
        increment: r.equivalent - old_equivalent,
        yielding: r.excess,
    };
    (stress, state)
}

/// The returned stress of J2 elements, one per lane, with what their forces need.
#[derive(Debug, Clone, Copy)]
pub struct PlasticStress<T> {
    f: [T; 9],
    d: [T; 9],
    v: T,
    e: Sym<T>,
    stress: Sym<T>,
    stored_energy: T,
    dissipation: T,
}

impl<T: Lanes> PlasticStress<T> {
    /// The elements' nodal forces and energies.
    #[inline(always)]
    pub fn forces(&self) -> ElementLanes<T> {
        let p = first_piola_from_biot_stress(&self.f, &self.e, &self.stress);
        ElementLanes {
            nodal: nodal_forces(&p, &self.d, self.v),
            strain_energy: self.v * self.stored_energy,
            plastic_work: self.v * self.dissipation,
            jacobian: det3_fused(&self.f),
        }
    }
}

/// Plastic states after a step, one element per lane.
#[derive(Debug, Clone, Copy)]
pub struct PlasticLanes<T> {
    /// Plastic strain (Sym order).
    pub strain: [T; 6],
    /// Equivalent plastic strain (–).
    pub equivalent: T,
    /// What the equivalent plastic strain gained in the step (–).
    pub increment: T,
    /// > 0 where the lane yielded; the other lanes' states are their old ones, bit for bit.
    pub yielding: T,
}

impl<T: Lanes> PlasticLanes<T> {
    /// The states as records of seven f64 ([`PlasticPoint::as_records`]), one per lane.
    #[inline(always)]
    pub fn rows(&self) -> [T; 7] {
        let s = &self.strain;
        [s[0], s[1], s[2], s[3], s[4], s[5], self.equivalent]
    }

    /// The state of lane `l`, given the lanes as arrays ([`Self::to_arrays`]).
    #[inline(always)]
    pub fn point(arrays: &([T::Array; 6], T::Array), l: usize) -> PlasticPoint {
        PlasticPoint {
            strain: build(0.0, |k| arrays.0[k][l]),
            equivalent: arrays.1[l],
        }
    }

    /// The lanes as one array per quantity.
    #[inline(always)]
    pub fn to_arrays(&self) -> ([T::Array; 6], T::Array) {
        (
            build(T::Array::default(), |k| self.strain[k].to_array()),
            self.equivalent.to_array(),
        )
    }
}

/// F = Ds·Dm⁻¹, Dm⁻¹ and V0 of `T::WIDTH` elements, one per lane, gathered straight from
/// the positions ([`Lanes::gather_corners`]) and loaded from the lane-blocked reference
/// data ([`Lanes::load_rows`]): no per-element copy in between, which the vector loads
/// would stall on.
#[inline(always)]
fn deformation_lanes<T: Lanes>(
    tets: &TetNodes,
    first: usize,
    reference: &ReferenceBlock,
    lane0: usize,
) -> ([T; 9], [T; 9], T) {
    let xl = T::gather_corners(tets, first);
    let record: [T; 10] = T::load_rows(&reference.fields, lane0);
    let mut d = [T::splat(0.0); 9];
    d.copy_from_slice(&record[..9]);
    let v = record[9];
    (crate::math::mat_mul_fused(&edge_matrix(&xl), &d), d, v)
}

/// f_{1,2,3} = columns of H = −V0 P Dm⁻ᵀ, f_0 = −(f_1 + f_2 + f_3) (N).
#[inline(always)]
fn nodal_forces<T: Lanes>(p: &[T; 9], d: &[T; 9], v: T) -> [[T; 3]; 4] {
    // H[i][j] = −V0 Σ_k P[i][k] Dm⁻¹[j][k]
    let mut nodal = [[T::splat(0.0); 3]; 4];
    for j in 0..3 {
        for i in 0..3 {
            let (r, c) = (3 * i, 3 * j);
            nodal[j + 1][i] = -v * dot3(p[r], d[c], p[r + 1], d[c + 1], p[r + 2], d[c + 2]);
        }
    }
    for i in 0..3 {
        nodal[0][i] = -(nodal[1][i] + nodal[2][i] + nodal[3][i]);
    }
    nodal
}

/// Largest eigenvalue of the small-strain element stiffness K_e = V0 Bᵀ D B (N/m).
///
/// The nonzero spectrum of the 12×12 K_e equals that of the 6×6 V0·Lᵀ(B Bᵀ)L with
/// D = L Lᵀ, so a 6×6 symmetric eigenproblem gives the exact value. With a lumped mass
/// m = ρV0/4 per node, ω_e² = λ_max(K_e)/m bounds the global ω_max from above
/// (element eigenvalue inequality), so Δt = 2/ω_e is a safe explicit step.
pub fn max_stiffness_eigenvalue(reference: &TetReference, lambda: f64, mu: f64) -> f64 {
    use nalgebra::{Matrix6, SMatrix};
    let g = reference.shape_gradients();
    // B: 6×12 strain-displacement (Voigt: xx, yy, zz, yz, xz, xy; engineering shear).
    let mut b = SMatrix::<f64, 6, 12>::zeros();
    for (a, ga) in g.iter().enumerate() {
        let c = 3 * a;
        b[(0, c)] = ga[0];
        b[(1, c + 1)] = ga[1];
        b[(2, c + 2)] = ga[2];
        b[(3, c + 1)] = ga[2];
        b[(3, c + 2)] = ga[1];
        b[(4, c)] = ga[2];
        b[(4, c + 2)] = ga[0];
        b[(5, c)] = ga[1];
        b[(5, c + 1)] = ga[0];
    }
    let mut d = Matrix6::<f64>::zeros();
    for i in 0..3 {
        for j in 0..3 {
            d[(i, j)] = lambda;
        }
        d[(i, i)] = lambda + 2.0 * mu;
        d[(i + 3, i + 3)] = mu;
    }
    let l = match d.cholesky() {
        Some(c) => c.l(),
        None => return f64::INFINITY,
    };
    let bbt = b * b.transpose();
    let m = l.transpose() * bbt * l;
    let eig = m.symmetric_eigenvalues();
    reference.volume * eig.iter().cloned().fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::ElasticParameters;

    fn regular_tet(h: f64) -> [[f64; 3]; 4] {
        [
            [0.0, 0.0, 0.0],
            [h, 0.0, 0.0],
            [0.5 * h, 0.5 * 3f64.sqrt() * h, 0.0],
            [0.5 * h, 3f64.sqrt() / 6.0 * h, (2.0f64 / 3.0).sqrt() * h],
        ]
    }

    #[test]
    fn forces_sum_to_zero_and_are_energy_gradient() {
        let p = ElasticParameters::paper_glass();
        for kind in [
            crate::material::ElasticLawKind::StVenantKirchhoff,
            crate::material::ElasticLawKind::Biot,
        ] {
            forces_are_energy_gradient(&crate::material::MaterialLaw::new(&p, kind, None));
        }
    }

    fn forces_are_energy_gradient(m: &MaterialLaw) {
        let x0 = regular_tet(1e-5);
        let r = TetReference::new(x0).unwrap();
        let mut x = x0;
        // a strain of a few per cent, where the laws differ
        x[2][0] += 2e-7;
        x[3][1] -= 1e-7;
        x[1][2] += 3e-7;
        let ef = tet_forces(&x, &r, m, None);
        for i in 0..3 {
            let s: f64 = ef.nodal.iter().map(|f| f[i]).sum();
            assert!(s.abs() < 1e-12 * ef.nodal[1][i].abs().max(1.0));
        }
        // f = −∂U/∂x, checked by central differences
        let h = 1e-12;
        for a in 0..4 {
            for i in 0..3 {
                let mut xp = x;
                xp[a][i] += h;
                let mut xm = x;
                xm[a][i] -= h;
                let du = (tet_forces(&xp, &r, m, None).strain_energy
                    - tet_forces(&xm, &r, m, None).strain_energy)
                    / (2.0 * h);
                let f = ef.nodal[a][i];
                assert!(
                    (f + du).abs() < 1e-5 * f.abs().max(1e-3),
                    "node {a} dir {i}: {f} vs {}",
                    -du
                );
            }
        }
    }

    #[test]
    fn regular_tet_stable_step_matches_theory() {
        // docs/THEORY.md §8: regular tet, lumped mass: Δt_crit = 0.565 h / c_p (for ν = 0.22).
        let p = ElasticParameters::paper_glass();
        let (lambda, mu) = p.lame();
        let h = 1e-5;
        let r = TetReference::new(regular_tet(h)).unwrap();
        let k = max_stiffness_eigenvalue(&r, lambda, mu);
        let m = p.density * r.volume / 4.0;
        let dt = 2.0 / (k / m).sqrt();
        let ratio = dt * p.dilatational_wave_speed() / h;
        assert!((ratio - 0.565).abs() < 0.01, "Δt·c_p/h = {ratio}");
    }

    #[test]
    fn inverted_tet_is_rejected() {
        let mut x = regular_tet(1.0);
        x.swap(1, 2);
        assert!(TetReference::new(x).is_none());
    }
}
