//! The integrator's group of eight nodes in AVX2 registers, as two halves of four nodes,
//! for the steps [`super::groups_avx512`] takes (no gravity; mass damping or no body
//! force at all).
//!
//! Why: the generic group ([`super::update_group`]) builds its lanes element by element
//! through the stack, which on the AVX2 path took 4.6–5.7 ms per pass over 659 k nodes on
//! the Zen 4 guest against 2.8 ms for the AVX-512 registers (docs/BENCHMARKS.md, session
//! 76). AVX2 permutes across two registers only by 128-bit halves, so four records of
//! three f64 come in as eight 128-bit halves and three in-lane shuffles
//! ([`Register::load_components`]), and go back as three shuffles, three lane swaps and
//! three full stores; four padded forces are a 4 × 4 transpose. The update itself is
//! [`update_lanes`], shared with the AVX-512 group.

use super::group_lanes::{update_lanes, Register};
use super::{GroupForces, Inputs, LaneSums, LANES};
use std::arch::x86_64::*;

/// Nodes per register.
const HALF: usize = 4;

/// The two f64 at `p` and the two at `p + 6` (the same place two records on), side by
/// side in one register. A function, not a closure: a closure is compiled apart, without
/// the caller's target features.
#[inline(always)]
unsafe fn two_pairs(p: *const f64) -> __m256d {
    _mm256_insertf128_pd::<1>(
        _mm256_castpd128_pd256(_mm_loadu_pd(p)),
        _mm_loadu_pd(p.add(6)),
    )
}

impl Register for __m256d {
    const WIDTH: usize = HALF;
    const ALL_FINITE: u32 = 0b1111;
    #[inline(always)]
    unsafe fn splat(value: f64) -> Self {
        _mm256_set1_pd(value)
    }
    #[inline(always)]
    unsafe fn load(p: *const f64) -> Self {
        _mm256_loadu_pd(p)
    }
    #[inline(always)]
    unsafe fn store(p: *mut f64, value: Self) {
        _mm256_storeu_pd(p, value)
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        _mm256_add_pd(a, b)
    }
    #[inline(always)]
    unsafe fn mul(a: Self, b: Self) -> Self {
        _mm256_mul_pd(a, b)
    }
    #[inline(always)]
    unsafe fn div(a: Self, b: Self) -> Self {
        _mm256_div_pd(a, b)
    }
    #[inline(always)]
    unsafe fn max(a: Self, b: Self) -> Self {
        _mm256_max_pd(a, b)
    }
    #[inline(always)]
    unsafe fn abs(self) -> Self {
        _mm256_andnot_pd(_mm256_set1_pd(-0.0), self)
    }
    #[inline(always)]
    unsafe fn finite_lanes(self) -> u32 {
        let zero = _mm256_setzero_pd();
        _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(self, self), zero)) as u32
    }
    #[inline(always)]
    unsafe fn load_components(p: *const f64) -> [Self; 3] {
        let xy_02 = two_pairs(p); // x₀ y₀ | x₂ y₂
        let xy_13 = two_pairs(p.add(3)); // x₁ y₁ | x₃ y₃
        let zx = two_pairs(p.add(2)); // z₀ x₁ | z₂ x₃
        let yz = two_pairs(p.add(4)); // y₁ z₁ | y₃ z₃
        [
            _mm256_unpacklo_pd(xy_02, xy_13),
            _mm256_unpackhi_pd(xy_02, xy_13),
            _mm256_shuffle_pd::<0b1010>(zx, yz),
        ]
    }
    #[inline(always)]
    unsafe fn store_components(p: *mut f64, [x, y, z]: [Self; 3]) {
        let xy_02 = _mm256_unpacklo_pd(x, y); // x₀ y₀ | x₂ y₂
        let zx = _mm256_shuffle_pd::<0b1010>(z, x); // z₀ x₁ | z₂ x₃
        let yz = _mm256_shuffle_pd::<0b1111>(y, z); // y₁ z₁ | y₃ z₃
        _mm256_storeu_pd(p, _mm256_permute2f128_pd::<0x20>(xy_02, zx));
        _mm256_storeu_pd(p.add(4), _mm256_permute2f128_pd::<0x30>(yz, xy_02));
        _mm256_storeu_pd(p.add(8), _mm256_permute2f128_pd::<0x31>(zx, yz));
    }
    #[inline(always)]
    unsafe fn load_forces(p: *const f64) -> [Self; 3] {
        let (r0, r1) = (_mm256_loadu_pd(p), _mm256_loadu_pd(p.add(4)));
        let (r2, r3) = (_mm256_loadu_pd(p.add(8)), _mm256_loadu_pd(p.add(12)));
        let xz_01 = _mm256_unpacklo_pd(r0, r1); // x₀ x₁ | z₀ z₁
        let y_01 = _mm256_unpackhi_pd(r0, r1); // y₀ y₁ | pad
        let xz_23 = _mm256_unpacklo_pd(r2, r3);
        let y_23 = _mm256_unpackhi_pd(r2, r3);
        [
            _mm256_permute2f128_pd::<0x20>(xz_01, xz_23),
            _mm256_permute2f128_pd::<0x20>(y_01, y_23),
            _mm256_permute2f128_pd::<0x31>(xz_01, xz_23),
        ]
    }
}

/// Nodes `n..n + LANES` (`x`, `v`), none with a stored v_{n+½}, in a step whose body
/// forces are `forces` ([`GroupForces::of`] the step's): what [`super::update_node`] does
/// to each, node n + l into lane l of `sums`, as two halves of [`HALF`] lanes.
///
/// # Safety
/// The CPU must support AVX2; `x` and `v` hold [`LANES`] nodes, and `inputs` holds nodes
/// up to n + [`LANES`].
#[target_feature(enable = "avx2,fma")]
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
    // a loop over the halves, not a closure: a closure is compiled apart, without the
    // caller's target features
    for h in 0..LANES / HALF {
        let at = h * HALF;
        let (x, v) = (&mut x[at..], &mut v[at..]);
        update_lanes::<__m256d>(inputs, n + at, at, x, v, sums, forces);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shuffles sort four records into components and back.
    #[test]
    fn components_round_trip_through_the_shuffles() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let records: Vec<f64> = (0..12).map(|e| e as f64).collect();
        let forces: Vec<f64> = (0..16).map(|e| e as f64).collect();
        let mut back = vec![0.0; 12];
        // SAFETY: AVX2 is present (checked above); the buffers hold what is read
        unsafe {
            let c = __m256d::load_components(records.as_ptr());
            let lanes = c.map(|r| std::mem::transmute::<__m256d, [f64; 4]>(r));
            super::super::assert_sorted_into_components(lanes, 3);
            __m256d::store_components(back.as_mut_ptr(), c);
            let f = __m256d::load_forces(forces.as_ptr())
                .map(|r| std::mem::transmute::<__m256d, [f64; 4]>(r));
            super::super::assert_sorted_into_components(f, 4);
        }
        assert_eq!(back, records);
    }
}
