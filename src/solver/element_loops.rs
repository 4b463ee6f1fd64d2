//! The element loops of one force pass: one loop compiled per law (no per-element
//! dispatch), each in a portable build and an AVX2 build that evaluates four elements per
//! pass in f64 lanes (`crate::lanes`). Both builds give bitwise identical results: the
//! lanes are plain IEEE arithmetic, and forces are added element by element in element
//! order.
//!
//! Everything here runs inside the AVX2 function must inline into it, or each lane
//! operation becomes a call (the kernel then runs at a fifth of its speed): no
//! `std::array::from_fn`, no `map` on arrays, plain loops. `tests/element_kernel.rs`
//! guards the speed-up.

use super::element_schedule::ElementChunk;
use crate::element::{
    tet_forces, tet_forces_elastic, tet_forces_elastic_x4, tet_forces_plastic_x4, ElementForces,
    TetReference,
};
#[cfg(target_arch = "x86_64")]
use crate::lanes::F64x4;
use crate::lanes::Lanes;
use crate::material::{
    CorotationalLinear, ElasticLawKind, HyperelasticLaw, MaterialLaw, PlasticPoint,
    SecondOrderBiot, StVenantKirchhoff, J2,
};
use crate::model::Model;

/// Largest equivalent plastic strain one element may gain in one step. Explicit steps are
/// a fraction of a wave transit, so physical plastic flow adds far less; more means the
/// integration is exploding.
pub const MAX_PLASTIC_INCREMENT: f64 = 0.05;

/// The compiled element loop a run uses. Both give bitwise identical forces (lane-wise
/// IEEE arithmetic in the same order); AVX2 does four lanes per instruction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum KernelPath {
    #[default]
    Portable,
    Avx2,
}

impl KernelPath {
    /// AVX2 where the CPU has it, unless `MUFE_KERNEL=portable` asks for the portable loop
    /// (to compare the two on one machine).
    pub fn detect() -> Self {
        if std::env::var("MUFE_KERNEL").is_ok_and(|v| v == "portable") {
            return Self::Portable;
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Self::Avx2;
        }
        Self::Portable
    }

    /// The name recorded in the results' provenance.
    pub fn name(self) -> &'static str {
        match self {
            Self::Portable => "portable",
            Self::Avx2 => "avx2",
        }
    }
}

/// An element that failed: inverted, non-finite, or an exploding plastic increment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadElement {
    pub element: usize,
    /// det F (–).
    pub jacobian: f64,
    /// Equivalent plastic strain gained in this step (–).
    pub plastic_increment: f64,
}

impl BadElement {
    /// What went wrong, for the error line.
    pub fn describe(&self) -> String {
        if self.jacobian.is_nan() || self.jacobian <= 0.0 {
            format!("inverted (det F = {:.3e})", self.jacobian)
        } else if self.plastic_increment > MAX_PLASTIC_INCREMENT {
            format!(
                "gained {:.3e} equivalent plastic strain in one step (limit {MAX_PLASTIC_INCREMENT})",
                self.plastic_increment
            )
        } else {
            format!("has a non-finite force (det F = {:.3e})", self.jacobian)
        }
    }
}

/// Reduction of one element chunk.
#[derive(Debug, Clone, Copy, Default)]
pub struct ChunkResult {
    pub strain_energy: f64,
    pub plastic_work: f64,
    /// First failing element in the chunk, if any.
    pub bad_element: Option<BadElement>,
}

/// A slice that parallel tasks write through at indices they own exclusively.
pub(super) struct Disjoint<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: only handed to tasks that write disjoint indices (see `Pass`).
unsafe impl<T: Send> Sync for Disjoint<T> {}

impl<T> Disjoint<T> {
    pub(super) fn new(slice: &mut [T]) -> Self {
        Self {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
        }
    }

    /// # Safety
    /// No other task may access entry `i` while the returned reference lives.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    unsafe fn get(&self, i: usize) -> &mut T {
        debug_assert!(i < self.len);
        &mut *self.ptr.add(i)
    }
}

/// What every chunk of one force pass reads and writes. Chunks of one colour share no
/// node and own disjoint element (hence plastic-slot) ranges (`ElementSchedule`), and
/// colours run one after another, so no two tasks touch the same force or state.
pub(super) struct Pass<'a> {
    pub model: &'a Model,
    pub x: &'a [[f64; 3]],
    pub force: Disjoint<[f64; 3]>,
    pub plastic: Disjoint<PlasticPoint>,
}

/// Energies and the first failure of a chunk, element by element.
struct Tally {
    result: ChunkResult,
    first_element: usize,
}

impl Tally {
    fn new(first_element: usize) -> Self {
        Self {
            result: ChunkResult::default(),
            first_element,
        }
    }

    /// Element `k` of the chunk: V0·ψ and V0·plastic work (J), det F, and the equivalent
    /// plastic strain it gained.
    #[inline(always)]
    fn record(
        &mut self,
        k: usize,
        strain_energy: f64,
        plastic_work: f64,
        jacobian: f64,
        plastic_increment: f64,
    ) {
        let r = &mut self.result;
        if r.bad_element.is_none()
            && !(jacobian > 0.0
                && strain_energy.is_finite()
                && plastic_increment <= MAX_PLASTIC_INCREMENT)
        {
            r.bad_element = Some(BadElement {
                element: self.first_element + k,
                jacobian,
                plastic_increment,
            });
        }
        r.strain_energy += strain_energy;
        r.plastic_work += plastic_work;
    }
}

/// One chunk: its elements' forces added into the node forces, plastic states committed,
/// energies and the first failure returned.
///
/// # Safety
/// No other task may touch the chunk's nodes or plastic slots meanwhile (see [`Pass`]).
pub(super) unsafe fn evaluate_chunk(
    path: KernelPath,
    pass: &Pass,
    chunk: &ElementChunk,
) -> ChunkResult {
    let law = &pass.model.laws[chunk.law as usize];
    let (lambda, mu) = (law.lambda, law.mu);
    match (law.plastic, chunk.plastic_start, law.kind) {
        (Some(j2), Some(first_slot), _) => match path {
            #[cfg(target_arch = "x86_64")]
            KernelPath::Avx2 => evaluate_plastic_chunk_avx2(pass, chunk, law, &j2, first_slot),
            _ => evaluate_plastic_chunk::<f64>(pass, chunk, law, &j2, first_slot),
        },
        (_, _, ElasticLawKind::Biot) => {
            evaluate_elastic_chunk_on(path, pass, chunk, &SecondOrderBiot { lambda, mu })
        }
        (_, _, ElasticLawKind::StVenantKirchhoff) => {
            evaluate_elastic_chunk_on(path, pass, chunk, &StVenantKirchhoff { lambda, mu })
        }
        (_, _, ElasticLawKind::Corotational) => {
            evaluate_elastic_chunk_on(path, pass, chunk, &CorotationalLinear { lambda, mu })
        }
    }
}

#[inline(always)]
fn element_positions(x: &[[f64; 3]], t: &[u32; 4]) -> [[f64; 3]; 4] {
    [
        x[t[0] as usize],
        x[t[1] as usize],
        x[t[2] as usize],
        x[t[3] as usize],
    ]
}

/// Elements `4q..4q + 4` of a chunk's connectivity and reference data.
#[inline(always)]
fn quad<'a>(
    tets: &'a [[u32; 4]],
    references: &'a [TetReference],
    q: usize,
) -> Option<(&'a [[u32; 4]; 4], &'a [TetReference; 4])> {
    Some((
        tets.get(4 * q..)?.first_chunk::<4>()?,
        references.get(4 * q..)?.first_chunk::<4>()?,
    ))
}

/// # Safety
/// As [`evaluate_chunk`].
#[inline(always)]
unsafe fn add_nodal_forces(force: &Disjoint<[f64; 3]>, t: &[u32; 4], nodal: &[[f64; 3]; 4]) {
    for (n, f) in t.iter().zip(nodal) {
        let out = force.get(*n as usize);
        out[0] += f[0];
        out[1] += f[1];
        out[2] += f[2];
    }
}

/// The element loop of an elastic law: with lanes `T` wider than one (and a law that
/// vectorises) four elements per pass ([`tet_forces_elastic_x4`]), the last few one by
/// one.
///
/// # Safety
/// As [`evaluate_chunk`]; with `T` = [`F64x4`] the CPU must support AVX2.
#[inline(always)]
unsafe fn evaluate_elastic_chunk<L: HyperelasticLaw, T: Lanes>(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &L,
) -> ChunkResult {
    let range = chunk.elements.clone();
    let tets = &pass.model.tets[range.clone()];
    let references = &pass.model.tet_reference[range.clone()];
    let mut tally = Tally::new(range.start);
    let mut record = |k: usize, nodal: &[[f64; 3]; 4], strain_energy: f64, jacobian: f64| {
        add_nodal_forces(&pass.force, &tets[k], nodal);
        tally.record(k, strain_energy, 0.0, jacobian, 0.0);
    };
    let quads = if L::VECTORISES && T::WIDTH == 4 {
        tets.len() / 4
    } else {
        0
    };
    for q in 0..quads {
        let Some((t, r)) = quad(tets, references, q) else {
            break;
        };
        let (nodal, energy, jacobian) = tet_forces_elastic_x4::<L, T>(pass.x, t, r, law);
        for l in 0..4 {
            record(4 * q + l, &nodal[l], energy[l], jacobian[l]);
        }
    }
    for k in 4 * quads..tets.len() {
        let (nodal, energy, jacobian) =
            tet_forces_elastic(&element_positions(pass.x, &tets[k]), &references[k], law);
        record(k, &nodal, energy, jacobian);
    }
    tally.result
}

/// The element loop of a J2 material: four elements per pass with lanes `T` wider than
/// one ([`tet_forces_plastic_x4`]), the rest one by one. A state is written back only
/// where the step changed it.
///
/// # Safety
/// As [`evaluate_chunk`]; with `T` = [`F64x4`] the CPU must support AVX2.
#[inline(always)]
unsafe fn evaluate_plastic_chunk<T: Lanes>(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &MaterialLaw,
    j2: &J2,
    first_slot: usize,
) -> ChunkResult {
    let range = chunk.elements.clone();
    let tets = &pass.model.tets[range.clone()];
    let references = &pass.model.tet_reference[range.clone()];
    let mut tally = Tally::new(range.start);
    let mut record = |k: usize, forces: ElementForces| {
        add_nodal_forces(&pass.force, &tets[k], &forces.nodal);
        let point = pass.plastic.get(first_slot + k);
        let mut plastic_increment = 0.0;
        if let Some(p) = forces.point {
            plastic_increment = p.equivalent - point.equivalent;
            // an elastic step returns the state unchanged: not writing it back saves the
            // memory traffic of a dirty cache line
            if p != *point {
                *point = p;
            }
        }
        let (energy, work, jacobian) = (forces.strain_energy, forces.plastic_work, forces.jacobian);
        tally.record(k, energy, work, jacobian, plastic_increment);
    };
    let quads = if T::WIDTH == 4 { tets.len() / 4 } else { 0 };
    for q in 0..quads {
        let Some((t, r)) = quad(tets, references, q) else {
            break;
        };
        let at = |l: usize| &*pass.plastic.get(first_slot + 4 * q + l);
        let out = tet_forces_plastic_x4::<T>(pass.x, t, r, j2, [at(0), at(1), at(2), at(3)]);
        for l in 0..4 {
            let forces = ElementForces {
                nodal: out.nodal[l],
                strain_energy: out.strain_energy[l],
                plastic_work: out.plastic_work[l],
                jacobian: out.jacobian[l],
                point: Some(out.points[l]),
            };
            record(4 * q + l, forces);
        }
    }
    for k in 4 * quads..tets.len() {
        let point = *pass.plastic.get(first_slot + k);
        let xe = element_positions(pass.x, &tets[k]);
        record(k, tet_forces(&xe, &references[k], law, Some(&point)));
    }
    tally.result
}

/// [`evaluate_elastic_chunk`] compiled for AVX2, four elements per instruction.
///
/// # Safety
/// As [`evaluate_chunk`], and the CPU must support AVX2 ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn evaluate_elastic_chunk_avx2<L: HyperelasticLaw>(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &L,
) -> ChunkResult {
    evaluate_elastic_chunk::<L, F64x4>(pass, chunk, law)
}

/// [`evaluate_plastic_chunk`] compiled for AVX2, four elements per instruction.
///
/// # Safety
/// As [`evaluate_chunk`], and the CPU must support AVX2 ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn evaluate_plastic_chunk_avx2(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &MaterialLaw,
    j2: &J2,
    first_slot: usize,
) -> ChunkResult {
    evaluate_plastic_chunk::<F64x4>(pass, chunk, law, j2, first_slot)
}

/// # Safety
/// As [`evaluate_chunk`].
unsafe fn evaluate_elastic_chunk_on<L: HyperelasticLaw>(
    path: KernelPath,
    pass: &Pass,
    chunk: &ElementChunk,
    law: &L,
) -> ChunkResult {
    match path {
        #[cfg(target_arch = "x86_64")]
        KernelPath::Avx2 => evaluate_elastic_chunk_avx2(pass, chunk, law),
        _ => evaluate_elastic_chunk::<L, f64>(pass, chunk, law),
    }
}
