//! The integrator's group of eight nodes in AVX-512 registers, for a step without gravity
//! whose only body force is mass-proportional damping or none (the quasi-static cell's
//! two stages).
//!
//! Why: the generic group ([`super::update_group`]) builds its lanes element by element,
//! and the compiler assembles them through the stack; on the Zen 4 guest that pass took
//! 4.0 ms per 659 k nodes against 3.0 ms for a plain node-by-node loop over the same
//! arrays, and this one takes 2.8 ms (docs/BENCHMARKS.md, session 76). Here the three
//! vectors of eight nodes (x, v: 24 consecutive f64 each) come in as three full loads and
//! are sorted into components by two permutes per component, and go back the same way;
//! the padded forces come in as four loads and seven permutes. The update itself is
//! [`update_lanes`], shared with the AVX2 group.

use super::group_lanes::{update_lanes, Register};
use super::{GroupForces, Inputs, LaneSums, LANES};
use std::arch::x86_64::*;

/// Lane l of `permutex2var(a, idx, b)`: element `idx[l] & 7` of a (bit 3 clear) or b.
type Index = [i64; 8];

/// For component c of eight records of three f64 held in three registers (elements
/// 0..24): the indices that pick lanes 0.. from the first two registers, then the
/// indices that keep those and take the rest from the third.
const fn split_indices(c: usize) -> (Index, Index) {
    let (mut first, mut second) = ([0; 8], [0; 8]);
    let mut l = 0;
    while l < 8 {
        let e = 3 * l + c;
        if e < 16 {
            first[l] = e as i64;
            second[l] = l as i64;
        } else {
            second[l] = 8 + (e - 16) as i64;
        }
        l += 1;
    }
    (first, second)
}

/// For register j (elements 8j..8j+8) of eight records of three f64: the indices that
/// take components 0 and 1 from their two registers, then the indices that keep those
/// and take component 2 from the third.
const fn join_indices(j: usize) -> (Index, Index) {
    let (mut first, mut second) = ([0; 8], [0; 8]);
    let mut k = 0;
    while k < 8 {
        let e = 8 * j + k;
        let (c, l) = (e % 3, e / 3);
        match c {
            0 => first[k] = l as i64,
            1 => first[k] = 8 + l as i64,
            _ => {}
        }
        second[k] = if c == 2 { 8 + l as i64 } else { k as i64 };
        k += 1;
    }
    (first, second)
}

const SPLIT: [(Index, Index); 3] = [split_indices(0), split_indices(1), split_indices(2)];
const JOIN: [(Index, Index); 3] = [join_indices(0), join_indices(1), join_indices(2)];

#[inline(always)]
unsafe fn index(i: &Index) -> __m512i {
    _mm512_loadu_si512(i.as_ptr().cast())
}

/// `N` consecutive registers of eight f64 from `p`.
#[inline(always)]
unsafe fn load_registers<const N: usize>(p: *const f64) -> [__m512d; N] {
    // loops, not closures: a closure is compiled apart, without the caller's features
    let mut r = [_mm512_setzero_pd(); N];
    for (k, r) in r.iter_mut().enumerate() {
        *r = _mm512_loadu_pd(p.add(8 * k));
    }
    r
}

impl Register for __m512d {
    const WIDTH: usize = LANES;
    const ALL_FINITE: u32 = 0xff;
    #[inline(always)]
    unsafe fn splat(value: f64) -> Self {
        _mm512_set1_pd(value)
    }
    #[inline(always)]
    unsafe fn load(p: *const f64) -> Self {
        _mm512_loadu_pd(p)
    }
    #[inline(always)]
    unsafe fn store(p: *mut f64, value: Self) {
        _mm512_storeu_pd(p, value)
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        _mm512_add_pd(a, b)
    }
    #[inline(always)]
    unsafe fn mul(a: Self, b: Self) -> Self {
        _mm512_mul_pd(a, b)
    }
    #[inline(always)]
    unsafe fn div(a: Self, b: Self) -> Self {
        _mm512_div_pd(a, b)
    }
    #[inline(always)]
    unsafe fn max(a: Self, b: Self) -> Self {
        _mm512_max_pd(a, b)
    }
    #[inline(always)]
    unsafe fn abs(self) -> Self {
        _mm512_abs_pd(self)
    }
    #[inline(always)]
    unsafe fn finite_lanes(self) -> u32 {
        let zero = _mm512_setzero_pd();
        u32::from(_mm512_cmp_pd_mask::<_CMP_EQ_OQ>(
            _mm512_sub_pd(self, self),
            zero,
        ))
    }
    /// Three full loads, two permutes per component.
    #[inline(always)]
    unsafe fn load_components(p: *const f64) -> [Self; 3] {
        let r = load_registers::<3>(p);
        let mut c = [_mm512_setzero_pd(); 3];
        for (c, (first, second)) in c.iter_mut().zip(&SPLIT) {
            let t = _mm512_permutex2var_pd(r[0], index(first), r[1]);
            *c = _mm512_permutex2var_pd(t, index(second), r[2]);
        }
        c
    }
    #[inline(always)]
    unsafe fn store_components(p: *mut f64, c: [Self; 3]) {
        for (j, (first, second)) in JOIN.iter().enumerate() {
            let t = _mm512_permutex2var_pd(c[0], index(first), c[1]);
            _mm512_storeu_pd(p.add(8 * j), _mm512_permutex2var_pd(t, index(second), c[2]));
        }
    }
    #[inline(always)]
    unsafe fn load_forces(p: *const f64) -> [Self; 3] {
        let r = load_registers::<4>(p);
        // per pair of registers: [x y] and [z pad] of their four nodes
        let xy = _mm512_setr_epi64(0, 4, 8, 12, 1, 5, 9, 13);
        let zw = _mm512_setr_epi64(2, 6, 10, 14, 3, 7, 11, 15);
        let (xy_lo, zw_lo) = (
            _mm512_permutex2var_pd(r[0], xy, r[1]),
            _mm512_permutex2var_pd(r[0], zw, r[1]),
        );
        let (xy_hi, zw_hi) = (
            _mm512_permutex2var_pd(r[2], xy, r[3]),
            _mm512_permutex2var_pd(r[2], zw, r[3]),
        );
        let low = _mm512_setr_epi64(0, 1, 2, 3, 8, 9, 10, 11);
        let high = _mm512_setr_epi64(4, 5, 6, 7, 12, 13, 14, 15);
        [
            _mm512_permutex2var_pd(xy_lo, low, xy_hi),
            _mm512_permutex2var_pd(xy_lo, high, xy_hi),
            _mm512_permutex2var_pd(zw_lo, low, zw_hi),
        ]
    }
}

/// Nodes `n..n + LANES` (`x`, `v`), none with a stored v_{n+½}, in a step whose body
/// forces are `forces` ([`GroupForces::of`] the step's): what [`super::update_node`] does
/// to each, node n + l into lane l of `sums`.
///
/// # Safety
/// The CPU must support AVX-512F; `x` and `v` hold [`LANES`] nodes, and `inputs` holds
/// nodes up to n + [`LANES`].
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
pub(super) unsafe fn update_group(
    inputs: &Inputs,
    n: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    sums: &mut LaneSums,
    forces: GroupForces,
) {
    debug_assert!(x.len() == LANES && v.len() == LANES);
    assert!(n + LANES <= inputs.mass.len() && n + LANES <= inputs.force.len());
    update_lanes::<__m512d>(inputs, n, 0, x, v, sums, forces);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The permute tables sort eight records into components and back.
    #[test]
    fn components_round_trip_through_the_permutes() {
        if !std::arch::is_x86_feature_detected!("avx512f") {
            return;
        }
        let records: Vec<f64> = (0..24).map(|e| e as f64).collect();
        let forces: Vec<f64> = (0..32).map(|e| e as f64).collect();
        let mut back = vec![0.0; 24];
        // SAFETY: AVX-512F is present (checked above); the buffers hold what is read
        unsafe {
            let c = __m512d::load_components(records.as_ptr());
            let lanes = c.map(|r| std::mem::transmute::<__m512d, [f64; 8]>(r));
            super::super::assert_sorted_into_components(lanes, 3);
            __m512d::store_components(back.as_mut_ptr(), c);
            let f = __m512d::load_forces(forces.as_ptr())
                .map(|r| std::mem::transmute::<__m512d, [f64; 8]>(r));
            super::super::assert_sorted_into_components(f, 4);
        }
        assert_eq!(back, records);
    }
}
