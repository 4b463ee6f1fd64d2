//! The element loops of one force pass: one loop compiled per law (no per-element
//! dispatch), each in a portable build, an AVX2 build that evaluates four elements per
//! pass in f64 lanes (`crate::lanes`) and an AVX-512 build that evaluates eight. All give
//! bitwise identical results: the lanes are plain IEEE arithmetic, and forces are added
//! element by element in element order.
//!
//! Everything that runs inside a vector function must inline into it, or each lane
//! operation becomes a call (the kernel then runs at a fifth of its speed): no
//! `std::array::from_fn`, no `map` on arrays, plain loops. `tests/element_kernel.rs`
//! guards the speed-up.

use super::element_schedule::{ElementChunk, FirstTouches, TOUCH_BLOCK};
use crate::element::references::BLOCK;
use crate::element::{
    plastic_return_lanes, tet_forces, tet_forces_elastic, tet_forces_elastic_lanes, PlasticLanes,
    ReferenceBlock, TetReferences,
};
use crate::error::InputError;
use crate::lanes::{prefetch, prefetch_to_l2, touch_pointee, Lanes, NodeForce, TetNodes};
#[cfg(target_arch = "x86_64")]
use crate::lanes::{F64x4, F64x8};
use crate::material::{
    CorotationalLinear, ElasticLawKind, HyperelasticLaw, MaterialLaw, PlasticPoint,
    SecondOrderBiot, StVenantKirchhoff, J2,
};
use crate::model::Model;

/// Largest equivalent plastic strain one element may gain in one step. Explicit steps are
/// a fraction of a wave transit, so physical plastic flow adds far less; more means the
/// integration is exploding.
pub const MAX_PLASTIC_INCREMENT: f64 = 0.05;

/// The compiled element loop a run uses. All give bitwise identical forces (lane-wise
/// IEEE arithmetic in the same order); AVX2 does four lanes per instruction, AVX-512
/// eight.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum KernelPath {
    #[default]
    Portable,
    Avx2,
    Avx512,
}

impl KernelPath {
    /// Every path, widest first.
    pub(crate) const ALL: [Self; 3] = [Self::Avx512, Self::Avx2, Self::Portable];

    /// The widest path the CPU supports, unless `MUFE_KERNEL` names another one it
    /// supports (to compare them on one machine).
    pub fn detect() -> Self {
        let widest = Self::ALL.into_iter().find(|p| p.is_supported());
        Self::requested()
            .filter(|p| p.is_supported())
            .or(widest)
            .unwrap_or_default()
    }

    /// The path `MUFE_KERNEL` names, if it names one.
    fn requested() -> Option<Self> {
        let asked = std::env::var("MUFE_KERNEL").ok()?;
        Self::ALL.into_iter().find(|p| p.name() == asked.trim())
    }

    /// Checks `MUFE_KERNEL`: unset, or the name of a path this CPU can run (the command
    /// line checks it before a run, so that a typo or a path this CPU lacks is an error,
    /// not a silent fallback).
    pub fn check_requested() -> Result<(), InputError> {
        let Ok(asked) = std::env::var("MUFE_KERNEL") else {
            return Ok(());
        };
        let wrong = |message: String| InputError::new("<environment>", "MUFE_KERNEL", message);
        let Some(path) = Self::requested() else {
            return Err(wrong(format!(
                "'{}' is not an element kernel (portable, avx2 or avx512)",
                crate::error::echo(&asked)
            )));
        };
        if !path.is_supported() {
            let here: Vec<&str> = (Self::ALL.iter().rev())
                .filter(|p| p.is_supported())
                .map(|p| p.name())
                .collect();
            return Err(wrong(format!(
                "this CPU cannot run the {} kernel (it can run: {})",
                path.name(),
                here.join(", ")
            )));
        }
        Ok(())
    }

    /// Whether this CPU can run the path.
    pub fn is_supported(self) -> bool {
        match self {
            Self::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => {
                std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The name recorded in the results' provenance.
    pub fn name(self) -> &'static str {
        match self {
            Self::Portable => "portable",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
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

    /// Entries `first..first + len`, read only.
    ///
    /// # Safety
    /// No other task may write them while the returned slice lives.
    #[inline(always)]
    unsafe fn slice(&self, first: usize, len: usize) -> &[T] {
        debug_assert!(first + len <= self.len);
        std::slice::from_raw_parts(self.ptr.add(first), len)
    }

    /// Entries `first..first + len`, to write.
    ///
    /// # Safety
    /// No other task may access them while the returned slice lives.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub(super) unsafe fn slice_mut(&self, first: usize, len: usize) -> &mut [T] {
        debug_assert!(first + len <= self.len);
        std::slice::from_raw_parts_mut(self.ptr.add(first), len)
    }

    /// The first entry, for writes at indices below `len` that no other task accesses.
    #[inline(always)]
    pub(super) fn as_mut_ptr(&self) -> *mut T {
        self.ptr
    }

    /// Number of entries.
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// # Safety
    /// No other task may access entry `i` while the returned reference lives.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub(super) unsafe fn get(&self, i: usize) -> &mut T {
        debug_assert!(i < self.len);
        &mut *self.ptr.add(i)
    }
}

/// What every chunk of one force pass reads and writes. Chunks own disjoint element (hence
/// plastic-slot) ranges, and chunks that share a node never run at once (`ElementSchedule`,
/// `ChunkOrder`), so no two tasks touch the same force or state.
pub(super) struct Pass<'a> {
    pub model: &'a Model,
    pub x: &'a [[f64; 3]],
    pub force: Disjoint<NodeForce>,
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
        self.check(k, strain_energy, jacobian, plastic_increment);
        self.result.strain_energy += strain_energy;
        self.result.plastic_work += plastic_work;
    }

    /// Notes element `k` as the chunk's first failure if it failed (an inverted element,
    /// a non-finite energy, too much plastic strain in one step), adding nothing.
    #[inline(always)]
    fn check(&mut self, k: usize, strain_energy: f64, jacobian: f64, plastic_increment: f64) {
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
    }
}

/// How many partial sums an elastic chunk's strain energy is gathered in: element k into
/// sum k mod 8, in element order; the chunk's energy is then the eight summed in order.
/// Every kernel path (one, four or eight lanes; a chunk starts a reference block, so k is
/// counted from a multiple of eight) adds the same numbers in the same order, and a path
/// with lanes adds a group's energies in one vector addition where a sum in element order
/// was a chain of eight scalar additions per group.
const ENERGY_SUMS: usize = BLOCK;

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
            #[cfg(target_arch = "x86_64")]
            KernelPath::Avx512 => evaluate_plastic_chunk_avx512(pass, chunk, law, &j2, first_slot),
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

/// Groups of lanes whose element data is requested ahead of their evaluation. A chunk's
/// reference records (80 B per element) are read once per step, far from where the last
/// step left them in cache: on the 2000-sphere block the load of the first record of a
/// group was a quarter of the kernel's time, waiting on memory (docs/BENCHMARKS.md,
/// session 32), because a chunk is too short for the hardware prefetcher to lock on.
const PREFETCH_GROUPS: usize = 4;

/// A chunk's reference blocks: its element k is lane k mod 8 of its block k / 8 (a chunk
/// starts a block: `element::references`).
struct ChunkBlocks<'a> {
    blocks: &'a [ReferenceBlock],
}

impl<'a> ChunkBlocks<'a> {
    fn of(references: &'a TetReferences, elements: std::ops::Range<usize>) -> Self {
        if elements.is_empty() {
            return Self { blocks: &[] };
        }
        let (first, lane) = references.slot(elements.start);
        assert_eq!(lane, 0, "a chunk starts a reference block");
        let count = elements.len().div_ceil(BLOCK);
        Self {
            blocks: &references.blocks()[first..first + count],
        }
    }

    /// The block of chunk element `k` and its lane.
    #[inline(always)]
    fn at(&self, k: usize) -> (&'a ReferenceBlock, usize) {
        (&self.blocks[k / BLOCK], k % BLOCK)
    }

    /// Prefetches block `b` of the chunk (its ten lines, one per field), if there is one.
    #[inline(always)]
    fn prefetch_block(&self, b: usize) {
        if let Some(block) = self.blocks.get(b) {
            prefetch(block as *const ReferenceBlock, 1);
        }
    }
}

/// Requests the position and force of each node a chunk's elements first reach, some
/// groups before the first of them is evaluated, each node once ([`FirstTouches`]).
struct NodesAhead<'a> {
    touches: &'a FirstTouches,
    x: *const [f64; 3],
    force: *const NodeForce,
    /// The next grain's nodes to hint into L2 ([`ElementChunk::next_grain_nodes`]), and
    /// how many per touch block.
    next_grain: std::ops::Range<usize>,
    next_per_block: usize,
}

impl<'a> NodesAhead<'a> {
    fn of(chunk: &'a ElementChunk, pass: &Pass) -> Self {
        let next_grain = chunk.next_grain_nodes.clone();
        let blocks = chunk.elements.len().div_ceil(TOUCH_BLOCK).max(1);
        Self {
            touches: &chunk.first_touches,
            x: pass.x.as_ptr(),
            force: pass.force.as_mut_ptr().cast_const(),
            next_per_block: next_grain.len().div_ceil(blocks),
            next_grain,
        }
    }

    /// Requests the nodes first reached by the elements of touch block `b` (chunk elements
    /// `TOUCH_BLOCK·b..`), if the chunk lists any.
    #[inline(always)]
    fn request_block(&self, b: usize) {
        let next = self.next_grain.start + b * self.next_per_block;
        if next < self.next_grain.end {
            let count = self.next_per_block.min(self.next_grain.end - next);
            prefetch_to_l2(self.x.wrapping_add(next), count);
            prefetch_to_l2(self.force.wrapping_add(next), count);
        }
        let block_end = &self.touches.block_end;
        let Some(&end) = block_end.get(b) else {
            return;
        };
        // block b − 1's end, none before block 0 (b − 1 wraps to a missing entry)
        let start = block_end.get(b.wrapping_sub(1)).copied().unwrap_or(0);
        for &n in &self.touches.nodes[start as usize..end as usize] {
            touch_pointee(self.x.wrapping_add(n as usize));
            touch_pointee(self.force.wrapping_add(n as usize));
        }
    }
}

/// What a chunk's loop requests ahead of its groups: the reference block and first-touched
/// nodes of the elements [`PREFETCH_GROUPS`] groups on, once per block of eight, and
/// their plastic states (elements of plastic materials) group by group. Requested at fixed
/// block boundaries, with no running bounds to update: the bookkeeping of a range-based
/// version was 7 % (Biot) to 14 % (J2) of the kernel's instructions (docs/BENCHMARKS.md,
/// session 42).
struct Ahead<'a, T> {
    blocks: &'a ChunkBlocks<'a>,
    nodes: NodesAhead<'a>,
    /// The chunk's first plastic state and how many it has (none for an elastic law):
    /// a pointer, not a slice, as the loop writes the states meanwhile.
    states: (*const PlasticPoint, usize),
    lanes: std::marker::PhantomData<T>,
}

impl<'a, T: Lanes> Ahead<'a, T> {
    /// Elements requested ahead: a whole number of blocks (four groups of four or eight
    /// lanes are).
    const ELEMENTS: usize = {
        assert!(BLOCK == TOUCH_BLOCK);
        (PREFETCH_GROUPS * T::WIDTH).next_multiple_of(BLOCK)
    };

    fn of(blocks: &'a ChunkBlocks<'a>, nodes: NodesAhead<'a>) -> Self {
        Self {
            blocks,
            nodes,
            states: (std::ptr::null(), 0),
            lanes: std::marker::PhantomData,
        }
    }

    /// Requests the first [`Self::ELEMENTS`] elements' data.
    #[inline(always)]
    fn start(&self) {
        for b in 0..Self::ELEMENTS / BLOCK {
            self.blocks.prefetch_block(b);
            self.nodes.request_block(b);
        }
        for k in (0..Self::ELEMENTS).step_by(T::WIDTH) {
            self.request_states(k);
        }
    }

    /// Before the group of `T::WIDTH` elements from `first`: requests the data of the group
    /// [`PREFETCH_GROUPS`] on.
    #[inline(always)]
    fn before_group(&self, first: usize) {
        let k = first + Self::ELEMENTS;
        if k.is_multiple_of(BLOCK) {
            self.blocks.prefetch_block(k / BLOCK);
            self.nodes.request_block(k / TOUCH_BLOCK);
        }
        self.request_states(k);
    }

    /// The plastic states of elements `k..k + T::WIDTH`, if the chunk has them all (a
    /// fixed count, so the prefetches unroll; the last groups' states are not requested).
    #[inline(always)]
    fn request_states(&self, k: usize) {
        let (first, count) = self.states;
        if k + T::WIDTH <= count {
            prefetch(first.wrapping_add(k), T::WIDTH);
        }
    }
}

/// The element loop of an elastic law: with lanes `T` wider than one (and a law that
/// vectorises) `T::WIDTH` elements per pass ([`tet_forces_elastic_lanes`]), the last few
/// one by one.
///
/// # Safety
/// As [`evaluate_chunk`]; the CPU must support the instructions of `T`.
#[inline(always)]
unsafe fn evaluate_elastic_chunk<L: HyperelasticLaw, T: Lanes>(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &L,
) -> ChunkResult {
    let range = chunk.elements.clone();
    let nodes = TetNodes::of(pass.x, &pass.model.tets, range.clone());
    assert!(pass.x.len() <= pass.force.len());
    let blocks = ChunkBlocks::of(&pass.model.tet_reference, range.clone());
    let mut tally = Tally::new(range.start);
    let width = T::WIDTH;
    let groups = if L::VECTORISES && width > 1 {
        nodes.len() / width
    } else {
        0
    };
    // a group's energies go to sums (g mod `per_group`)·width + lane = element mod 8
    let per_group = ENERGY_SUMS / width;
    let mut group_sums = [T::splat(0.0); ENERGY_SUMS];
    let ahead = Ahead::<T>::of(&blocks, NodesAhead::of(chunk, pass));
    if groups > 0 {
        ahead.start();
    }
    for g in 0..groups {
        let first = g * width;
        ahead.before_group(first);
        let (block, lane0) = blocks.at(first);
        let out = tet_forces_elastic_lanes::<L, T>(&nodes, first, block, lane0, law);
        // SAFETY: the nodes were checked against x, no longer than the forces; this
        // chunk's nodes are its task's alone (`Pass`)
        T::add_corner_forces(&out.nodal, &nodes, first, pass.force.as_mut_ptr());
        let sum = &mut group_sums[g % per_group];
        *sum = *sum + out.strain_energy;
        if !(out.jacobian.all_positive() && out.strain_energy.all_finite()) {
            let (energy, jacobian) = (out.strain_energy.to_array(), out.jacobian.to_array());
            for l in 0..width {
                tally.check(first + l, energy[l], jacobian[l], 0.0);
            }
        }
    }
    let mut sums = [0.0; ENERGY_SUMS];
    for (a, group_sum) in group_sums[..per_group].iter().enumerate() {
        let lanes = group_sum.to_array();
        for l in 0..width {
            sums[a * width + l] = lanes[l];
        }
    }
    for k in groups * width..nodes.len() {
        let (block, lane) = blocks.at(k);
        let reference = block.element(lane);
        let (nodal, energy, jacobian) = tet_forces_elastic(&nodes.corners_of(k), &reference, law);
        // SAFETY: as for the groups above
        f64::add_corner_forces(&nodal, &nodes, k, pass.force.as_mut_ptr());
        sums[k % ENERGY_SUMS] += energy;
        tally.check(k, energy, jacobian, 0.0);
    }
    tally.result.strain_energy = sums.iter().fold(0.0, |total, s| total + s);
    tally.result
}

/// The element loop of a J2 material: `T::WIDTH` elements per pass with lanes `T` wider
/// than one ([`plastic_return_lanes`], the states stored, then the forces), the rest one
/// by one. A state is written back only where the step changed it.
///
/// # Safety
/// As [`evaluate_chunk`]; the CPU must support the instructions of `T`.
#[inline(always)]
unsafe fn evaluate_plastic_chunk<T: Lanes>(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &MaterialLaw,
    j2: &J2,
    first_slot: usize,
) -> ChunkResult {
    let range = chunk.elements.clone();
    let nodes = TetNodes::of(pass.x, &pass.model.tets, range.clone());
    assert!(pass.x.len() <= pass.force.len());
    let blocks = ChunkBlocks::of(&pass.model.tet_reference, range.clone());
    let mut tally = Tally::new(range.start);
    // the state after the step into slot `k`
    let commit = |k: usize, p: PlasticPoint| {
        let point = pass.plastic.get(first_slot + k);
        // an elastic step returns the state unchanged: not writing it back saves the
        // memory traffic of a dirty cache line
        if p != *point {
            *point = p;
        }
    };
    let width = T::WIDTH;
    let groups = if width > 1 { nodes.len() / width } else { 0 };
    let ahead = Ahead::<T> {
        states: (
            pass.plastic.as_mut_ptr().wrapping_add(first_slot),
            nodes.len(),
        ),
        ..Ahead::of(&blocks, NodesAhead::of(chunk, pass))
    };
    if groups > 0 {
        ahead.start();
    }
    for g in 0..groups {
        let first = g * width;
        ahead.before_group(first);
        let old = pass.plastic.slice(first_slot + first, width);
        let (block, lane0) = blocks.at(first);
        let (stress, state) = plastic_return_lanes::<T>(&nodes, first, block, lane0, j2, old);
        // the states are stored before the forces are computed, so that none is held in
        // registers across that computation (the stored states are the same whether or
        // not an element then fails)
        let all_elastic = (-state.yielding).all_positive();
        let all_plastic = state.yielding.all_positive();
        if all_elastic {
            // the common group: each state is its old one, bit for bit
        } else if all_plastic {
            // the common plastic group: every state changed, stored as rows
            let states = pass.plastic.slice_mut(first_slot + first, width);
            T::scatter_records(&state.rows(), PlasticPoint::as_records_mut(states));
        } else {
            let states = state.to_arrays();
            for l in 0..width {
                commit(first + l, PlasticLanes::<T>::point(&states, l));
            }
        }
        let out = stress.forces();
        // SAFETY: as in `evaluate_elastic_chunk`
        T::add_corner_forces(&out.nodal, &nodes, first, pass.force.as_mut_ptr());
        let strain_energy = out.strain_energy.to_array();
        let sound = out.jacobian.all_positive() && out.strain_energy.all_finite();
        if all_elastic && sound {
            // no lane yielded (plastic work and increment zero) and none failed: only the
            // energy to sum
            for l in 0..width {
                tally.result.strain_energy += strain_energy[l];
            }
        } else if all_plastic
            && sound
            && (T::splat(MAX_PLASTIC_INCREMENT) - state.increment).all_positive()
        {
            let plastic_work = out.plastic_work.to_array();
            for l in 0..width {
                tally.result.strain_energy += strain_energy[l];
                tally.result.plastic_work += plastic_work[l];
            }
        } else {
            let plastic_work = out.plastic_work.to_array();
            let jacobian = out.jacobian.to_array();
            let increment = state.increment.to_array();
            for l in 0..width {
                let energy = strain_energy[l];
                tally.record(
                    first + l,
                    energy,
                    plastic_work[l],
                    jacobian[l],
                    increment[l],
                );
            }
        }
    }
    for k in groups * width..nodes.len() {
        let point = *pass.plastic.get(first_slot + k);
        let (block, lane) = blocks.at(k);
        let reference = block.element(lane);
        let forces = tet_forces(&nodes.corners_of(k), &reference, law, Some(&point));
        // SAFETY: as for the groups above
        f64::add_corner_forces(&forces.nodal, &nodes, k, pass.force.as_mut_ptr());
        let increment = forces.point.map_or(0.0, |p| {
            commit(k, p);
            p.equivalent - point.equivalent
        });
        let (energy, work, jacobian) = (forces.strain_energy, forces.plastic_work, forces.jacobian);
        tally.record(k, energy, work, jacobian, increment);
    }
    tally.result
}

/// [`evaluate_elastic_chunk`] compiled for AVX2, four elements per instruction.
///
/// # Safety
/// As [`evaluate_chunk`], and the CPU must support AVX2 and FMA ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
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
/// As [`evaluate_chunk`], and the CPU must support AVX2 and FMA ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn evaluate_plastic_chunk_avx2(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &MaterialLaw,
    j2: &J2,
    first_slot: usize,
) -> ChunkResult {
    evaluate_plastic_chunk::<F64x4>(pass, chunk, law, j2, first_slot)
}

/// [`evaluate_elastic_chunk`] compiled for AVX-512, eight elements per instruction.
///
/// # Safety
/// As [`evaluate_chunk`], and the CPU must support AVX-512F and VL ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
unsafe fn evaluate_elastic_chunk_avx512<L: HyperelasticLaw>(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &L,
) -> ChunkResult {
    evaluate_elastic_chunk::<L, F64x8>(pass, chunk, law)
}

/// [`evaluate_plastic_chunk`] compiled for AVX-512, eight elements per instruction.
///
/// # Safety
/// As [`evaluate_chunk`], and the CPU must support AVX-512F and VL ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
unsafe fn evaluate_plastic_chunk_avx512(
    pass: &Pass,
    chunk: &ElementChunk,
    law: &MaterialLaw,
    j2: &J2,
    first_slot: usize,
) -> ChunkResult {
    evaluate_plastic_chunk::<F64x8>(pass, chunk, law, j2, first_slot)
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
        #[cfg(target_arch = "x86_64")]
        KernelPath::Avx512 => evaluate_elastic_chunk_avx512(pass, chunk, law),
        _ => evaluate_elastic_chunk::<L, f64>(pass, chunk, law),
    }
}
