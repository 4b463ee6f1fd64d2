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
//! the padded forces come in as four loads and seven permutes.
//!
//! Every lane evaluates the expressions of [`super::update_node`] in its order, with no
//! fused multiply–add, so x, v and the lane sums are the same to the bit.

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

/// The x, y, z of eight consecutive records of three f64 at `p`, one register each.
#[inline(always)]
unsafe fn load_components(p: *const f64) -> [__m512d; 3] {
    let r = load_registers::<3>(p);
    let mut c = [_mm512_setzero_pd(); 3];
    for (c, (first, second)) in c.iter_mut().zip(&SPLIT) {
        let t = _mm512_permutex2var_pd(r[0], index(first), r[1]);
        *c = _mm512_permutex2var_pd(t, index(second), r[2]);
    }
    c
}

/// The inverse of [`load_components`]: eight records of three f64 to `p`.
#[inline(always)]
unsafe fn store_components(p: *mut f64, c: [__m512d; 3]) {
    for (j, (first, second)) in JOIN.iter().enumerate() {
        let t = _mm512_permutex2var_pd(c[0], index(first), c[1]);
        _mm512_storeu_pd(p.add(8 * j), _mm512_permutex2var_pd(t, index(second), c[2]));
    }
}

/// The x, y, z of eight consecutive padded forces (four f64 each) at `p`.
#[inline(always)]
unsafe fn load_forces(p: *const f64) -> [__m512d; 3] {
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

/// `math::dot` lane by lane: (p₀q₀ + p₁q₁) + p₂q₂.
#[inline(always)]
unsafe fn dot(p: &[__m512d; 3], q: &[__m512d; 3]) -> __m512d {
    _mm512_add_pd(
        _mm512_add_pd(_mm512_mul_pd(p[0], q[0]), _mm512_mul_pd(p[1], q[1])),
        _mm512_mul_pd(p[2], q[2]),
    )
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
    let dt = _mm512_set1_pd(inputs.dt);
    let m = _mm512_loadu_pd(inputs.mass.as_ptr().add(n));
    let a = load_components(v.as_ptr().cast());
    let mut f = load_forces(inputs.force.as_ptr().add(n).cast());
    let mut fd = [_mm512_setzero_pd(); 3];
    if let GroupForces::MassDamped(alpha) = forces {
        // BodyForces::total_force: f + (w + f_d), f_d = −α m v, w = 0 without gravity
        let am = _mm512_mul_pd(_mm512_set1_pd(-alpha), m);
        let w = _mm512_setzero_pd();
        for i in 0..3 {
            fd[i] = _mm512_mul_pd(am, a[i]);
            f[i] = _mm512_add_pd(f[i], _mm512_add_pd(w, fd[i]));
        }
    }
    // predict_along: v + dt·f / m (loops, not closures, as in `load_components`)
    let mut b = [_mm512_setzero_pd(); 3];
    for i in 0..3 {
        b[i] = _mm512_add_pd(a[i], _mm512_div_pd(_mm512_mul_pd(dt, f[i]), m));
    }
    // LaneSums::add: ½ m (a·b), then the largest |b| component by component
    let kinetic = _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(0.5), m), dot(&a, &b));
    let lanes = sums.kinetic.as_mut_ptr();
    _mm512_storeu_pd(lanes, _mm512_add_pd(_mm512_loadu_pd(lanes), kinetic));
    let fastest = sums.max_speed.as_mut_ptr();
    let mut max = _mm512_loadu_pd(fastest);
    for c in b {
        // max(|c|, max) is |c| where |c| > max, else max: the `if` of LaneSums::add
        max = _mm512_max_pd(_mm512_abs_pd(c), max);
    }
    _mm512_storeu_pd(fastest, max);
    if let GroupForces::MassDamped(_) = forces {
        let before = sums.damping_before.as_mut_ptr();
        _mm512_storeu_pd(before, _mm512_add_pd(_mm512_loadu_pd(before), dot(&fd, &a)));
        let after = sums.damping_after.as_mut_ptr();
        _mm512_storeu_pd(after, _mm512_add_pd(_mm512_loadu_pd(after), dot(&fd, &b)));
    }
    // b − b is 0 exactly where b is finite
    let zero = _mm512_setzero_pd();
    let mut finite = 0xffu8;
    for c in b {
        finite &= _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(_mm512_sub_pd(c, c), zero);
    }
    if finite != 0xff {
        let b = std::mem::transmute::<[__m512d; 3], [[f64; LANES]; 3]>(b);
        for l in 0..LANES {
            sums.check_finite(n + l, &[b[0][l], b[1][l], b[2][l]]);
        }
    }
    let p = x.as_mut_ptr().cast::<f64>();
    let xs = load_components(p);
    let mut moved = xs;
    for i in 0..3 {
        moved[i] = _mm512_add_pd(xs[i], _mm512_mul_pd(dt, b[i]));
    }
    store_components(p, moved);
    store_components(v.as_mut_ptr().cast(), b);
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
            let c = load_components(records.as_ptr());
            let lanes = c.map(|r| std::mem::transmute::<__m512d, [f64; 8]>(r));
            super::super::assert_sorted_into_components(lanes, 3);
            store_components(back.as_mut_ptr(), c);
            let f =
                load_forces(forces.as_ptr()).map(|r| std::mem::transmute::<__m512d, [f64; 8]>(r));
            super::super::assert_sorted_into_components(f, 4);
        }
        assert_eq!(back, records);
    }
}
