//! The integrator's group of eight nodes in AVX2 registers, as two halves of four nodes,
//! for the steps [`super::groups_avx512`] takes (no gravity; mass damping or no body
//! force at all).
//!
//! Why: the generic group ([`super::update_group`]) builds its lanes element by element
//! through the stack, which on the AVX2 path took 4.6–5.7 ms per pass over 659 k nodes on
//! the Zen 4 guest against 2.8 ms for the AVX-512 registers (docs/BENCHMARKS.md, session
//! 76). AVX2 permutes across two registers only by 128-bit halves, so four records of
//! three f64 come in as eight 128-bit halves and three in-lane shuffles
//! ([`load_components`]), and go back as three shuffles, three lane swaps and three full
//! stores; four padded forces are a 4 × 4 transpose.
//!
//! Every lane evaluates the expressions of [`super::update_node`] in its order, with no
//! fused multiply–add, so x, v and the lane sums are the same to the bit
//! (`a_group_of_lanes_is_its_nodes_one_by_one_to_the_bit` runs every path the CPU has).

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

/// The x, y, z of four consecutive records of three f64 at `p` (x₀ y₀ z₀ x₁ … z₃), one
/// register each.
#[inline(always)]
unsafe fn load_components(p: *const f64) -> [__m256d; 3] {
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

/// The inverse of [`load_components`]: four records of three f64 to `p`.
#[inline(always)]
unsafe fn store_components(p: *mut f64, [x, y, z]: [__m256d; 3]) {
    let xy_02 = _mm256_unpacklo_pd(x, y); // x₀ y₀ | x₂ y₂
    let zx = _mm256_shuffle_pd::<0b1010>(z, x); // z₀ x₁ | z₂ x₃
    let yz = _mm256_shuffle_pd::<0b1111>(y, z); // y₁ z₁ | y₃ z₃
    _mm256_storeu_pd(p, _mm256_permute2f128_pd::<0x20>(xy_02, zx));
    _mm256_storeu_pd(p.add(4), _mm256_permute2f128_pd::<0x30>(yz, xy_02));
    _mm256_storeu_pd(p.add(8), _mm256_permute2f128_pd::<0x31>(zx, yz));
}

/// The x, y, z of four consecutive padded forces (four f64 each) at `p`.
#[inline(always)]
unsafe fn load_forces(p: *const f64) -> [__m256d; 3] {
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

/// `math::dot` lane by lane: (p₀q₀ + p₁q₁) + p₂q₂.
#[inline(always)]
unsafe fn dot(p: &[__m256d; 3], q: &[__m256d; 3]) -> __m256d {
    _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(p[0], q[0]), _mm256_mul_pd(p[1], q[1])),
        _mm256_mul_pd(p[2], q[2]),
    )
}

/// `*lanes += value`, four lanes.
#[inline(always)]
unsafe fn add_to(lanes: *mut f64, value: __m256d) {
    _mm256_storeu_pd(lanes, _mm256_add_pd(_mm256_loadu_pd(lanes), value));
}

/// Nodes `n..n + LANES` (`x`, `v`), none with a stored v_{n+½}, in a step whose body
/// forces are `forces` ([`GroupForces::of`] the step's): what [`super::update_node`] does
/// to each, node n + l into lane l of `sums`.
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
    // loops over the halves, not closures: a closure is compiled apart, without the
    // caller's target features
    for h in 0..LANES / HALF {
        let first = n + h * HALF;
        let at = h * HALF;
        update_half(inputs, first, at, &mut x[at..], &mut v[at..], sums, forces);
    }
}

/// Nodes `first..first + HALF`, into lanes `at..at + HALF` of `sums`.
#[inline(always)]
unsafe fn update_half(
    inputs: &Inputs,
    first: usize,
    at: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    sums: &mut LaneSums,
    forces: GroupForces,
) {
    let dt = _mm256_set1_pd(inputs.dt);
    let m = _mm256_loadu_pd(inputs.mass.as_ptr().add(first));
    let a = load_components(v.as_ptr().cast());
    let mut f = load_forces(inputs.force.as_ptr().add(first).cast());
    let mut fd = [_mm256_setzero_pd(); 3];
    if let GroupForces::MassDamped(alpha) = forces {
        // BodyForces::total_force: f + (w + f_d), f_d = −α m v, w = 0 without gravity
        let am = _mm256_mul_pd(_mm256_set1_pd(-alpha), m);
        let w = _mm256_setzero_pd();
        for i in 0..3 {
            fd[i] = _mm256_mul_pd(am, a[i]);
            f[i] = _mm256_add_pd(f[i], _mm256_add_pd(w, fd[i]));
        }
    }
    // predict_along: v + dt·f / m
    let mut b = [_mm256_setzero_pd(); 3];
    for i in 0..3 {
        b[i] = _mm256_add_pd(a[i], _mm256_div_pd(_mm256_mul_pd(dt, f[i]), m));
    }
    // LaneSums::add: ½ m (a·b), then the largest |b| component by component
    let kinetic = _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(0.5), m), dot(&a, &b));
    add_to(sums.kinetic.as_mut_ptr().add(at), kinetic);
    let fastest = sums.max_speed.as_mut_ptr().add(at);
    let mut max = _mm256_loadu_pd(fastest);
    let sign = _mm256_set1_pd(-0.0);
    for c in b {
        // max(|c|, max) is |c| where |c| > max, else max: the `if` of LaneSums::add
        max = _mm256_max_pd(_mm256_andnot_pd(sign, c), max);
    }
    _mm256_storeu_pd(fastest, max);
    if let GroupForces::MassDamped(_) = forces {
        add_to(sums.damping_before.as_mut_ptr().add(at), dot(&fd, &a));
        add_to(sums.damping_after.as_mut_ptr().add(at), dot(&fd, &b));
    }
    // b − b is 0 exactly where b is finite
    let zero = _mm256_setzero_pd();
    let mut finite = 0b1111;
    for c in b {
        finite &= _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(c, c), zero));
    }
    if finite != 0b1111 {
        let b = std::mem::transmute::<[__m256d; 3], [[f64; HALF]; 3]>(b);
        for l in 0..HALF {
            sums.check_finite(first + l, &[b[0][l], b[1][l], b[2][l]]);
        }
    }
    let p = x.as_mut_ptr().cast::<f64>();
    let xs = load_components(p);
    let mut moved = xs;
    for i in 0..3 {
        moved[i] = _mm256_add_pd(xs[i], _mm256_mul_pd(dt, b[i]));
    }
    store_components(p, moved);
    store_components(v.as_mut_ptr().cast(), b);
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
            let c = load_components(records.as_ptr());
            let lanes = c.map(|r| std::mem::transmute::<__m256d, [f64; 4]>(r));
            super::super::assert_sorted_into_components(lanes, 3);
            store_components(back.as_mut_ptr(), c);
            let f =
                load_forces(forces.as_ptr()).map(|r| std::mem::transmute::<__m256d, [f64; 4]>(r));
            super::super::assert_sorted_into_components(f, 4);
        }
        assert_eq!(back, records);
    }
}
