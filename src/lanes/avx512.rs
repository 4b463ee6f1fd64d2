//! Eight f64 lanes in one AVX-512 register ([`F64x8`]).

use super::rows::{self, Transpose};
use super::{Lanes, NodeForce, TetNodes};
use std::arch::x86_64::*;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Eight f64 lanes in one AVX-512 register.
///
/// Every operation executes an AVX-512F (or, on 256-bit rows, AVX-512VL) instruction: use this type only in code that
/// runs after the CPU has been found to support AVX-512F and VL (`solver::forces::KernelPath`),
/// and compiled with that feature enabled, so that the operations inline to single
/// instructions.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct F64x8(__m512d);

impl Lanes for F64x8 {
    const WIDTH: usize = 8;
    type Array = [f64; 8];
    #[inline(always)]
    fn splat(v: f64) -> Self {
        // SAFETY: see the type's documentation (AVX-512F is present where this runs)
        Self(unsafe { _mm512_set1_pd(v) })
    }
    #[inline(always)]
    fn from_array(v: [f64; 8]) -> Self {
        // from registers, not through memory (store forwarding, as for F64x4)
        // SAFETY: as `splat`
        Self(unsafe { _mm512_set_pd(v[7], v[6], v[5], v[4], v[3], v[2], v[1], v[0]) })
    }
    #[inline(always)]
    fn to_array(self) -> [f64; 8] {
        let mut v = [0.0; 8];
        // SAFETY: as `splat`; the store writes exactly the eight values of `v`
        unsafe { _mm512_storeu_pd(v.as_mut_ptr(), self.0) };
        v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        // SAFETY: see the type's documentation
        Self(unsafe { _mm512_sqrt_pd(self.0) })
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        // SAFETY: see the type's documentation
        Self(unsafe { _mm512_fmadd_pd(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn neg_mul_add(self, a: Self, b: Self) -> Self {
        // SAFETY: as `mul_add`
        Self(unsafe { _mm512_fnmadd_pd(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn where_positive(self, then: Self, otherwise: Self) -> Self {
        // SAFETY: see the type's documentation
        unsafe {
            let positive = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(self.0, _mm512_setzero_pd());
            Self(_mm512_mask_blend_pd(positive, otherwise.0, then.0))
        }
    }
    #[inline(always)]
    fn all_positive(self) -> bool {
        // SAFETY: see the type's documentation
        unsafe { _mm512_cmp_pd_mask::<_CMP_GT_OQ>(self.0, _mm512_setzero_pd()) == 0xff }
    }
    #[inline(always)]
    fn all_finite(self) -> bool {
        // SAFETY: see the type's documentation
        // x − x is 0 for finite x, NaN for ±∞ and NaN
        unsafe {
            let difference = _mm512_sub_pd(self.0, self.0);
            _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(difference, _mm512_setzero_pd()) == 0xff
        }
    }
    #[inline(always)]
    unsafe fn add_corner_forces(
        nodal: &[[Self; 3]; 4],
        tets: &TetNodes,
        first: usize,
        force: *mut NodeForce,
    ) {
        let tets: &[[u32; 4]; 8] = (tets.tets[first..first + 8]).try_into().unwrap();
        // Each corner's (x, y, z, 0) of the eight elements as eight 256-bit rows (two to a
        // register, 16 registers for the four corners), then added element after element
        // and corner after corner: the one-element order, so every node's sum keeps its
        // bits. The loops have constant bounds, so they unroll and index nothing at run
        // time.
        let zero = _mm512_setzero_pd();
        let mut rows = [[_mm256_setzero_pd(); 8]; 4];
        for (a, corner) in rows.iter_mut().enumerate() {
            let [x, y, z] = nodal[a];
            __m512d::rows([x.0, y.0, z.0, zero], |l, row| corner[l] = row);
        }
        for (l, t) in tets.iter().enumerate() {
            for (a, corner) in rows.iter().enumerate() {
                // aligned: a NodeForce is 32 bytes on a 32-byte boundary
                let p = force.add(t[a] as usize) as *mut f64;
                _mm256_store_pd(p, _mm256_add_pd(_mm256_load_pd(p), corner[l]));
            }
        }
    }
    #[inline(always)]
    fn gather_corners(tets: &TetNodes, first: usize) -> [[Self; 3]; 4] {
        // SAFETY: see the type's documentation (AVX-512F is present where this runs)
        unsafe { rows::corners::<__m512d, _>(tets, first, Self) }
    }
    #[inline(always)]
    fn gather_records<const N: usize>(records: &[[f64; N]]) -> [Self; N] {
        // SAFETY: as `gather_corners`
        unsafe { rows::records::<__m512d, _, N>(records, Self) }
    }
    #[inline(always)]
    fn load_rows<const N: usize>(rows: &[[f64; 8]; N], lane0: usize) -> [Self; N] {
        assert_eq!(lane0, 0);
        // SAFETY: AVX-512F is present (see the type's documentation); a row is eight f64
        super::build(Self::splat(0.0), |k| unsafe {
            Self(_mm512_loadu_pd(rows[k].as_ptr()))
        })
    }
    #[inline(always)]
    fn scatter_records<const N: usize>(values: &[Self; N], records: &mut [[f64; N]]) {
        // SAFETY: as `gather_corners`
        unsafe { rows::scatter_records::<__m512d, _, N>(values, records, |v| v.0) }
    }
}

impl Transpose for __m512d {
    const ROWS: usize = 8;
    #[inline(always)]
    unsafe fn columns(row: impl Fn(usize) -> __m256d) -> [Self; 4] {
        transpose8x4(row)
    }
    #[inline(always)]
    unsafe fn rows(columns: [Self; 4], mut row: impl FnMut(usize, __m256d)) {
        // t0 = [c0[0], c1[0], c0[2], c1[2] | c0[4], c1[4], c0[6], c1[6]], and so on; one
        // two-source permute then holds two rows, one per half
        let [t0, t1, t2, t3] = interleave_pairs(columns);
        let low = _mm512_setr_epi64(0, 1, 8, 9, 2, 3, 10, 11);
        let high = _mm512_setr_epi64(4, 5, 12, 13, 6, 7, 14, 15);
        for (first, pair) in [
            (0, _mm512_permutex2var_pd(t0, low, t2)),
            (1, _mm512_permutex2var_pd(t1, low, t3)),
            (4, _mm512_permutex2var_pd(t0, high, t2)),
            (5, _mm512_permutex2var_pd(t1, high, t3)),
        ] {
            row(first, _mm512_castpd512_pd256(pair));
            row(first + 2, _mm512_extractf64x4_pd::<1>(pair));
        }
    }
}

/// Columns of eight rows of four f64: `row(l)` for l in 0..8 → `[c0, c1, c2, c3]` with
/// lane l of c_k equal to lane k of row l. Rows l and l + 4 share a register, so one
/// in-lane unpack and one two-source permute per column do the transpose.
///
/// # Safety
/// AVX-512F must be present.
#[inline(always)]
unsafe fn transpose8x4(row: impl Fn(usize) -> __m256d) -> [__m512d; 4] {
    let pair = |l: usize| _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(row(l)), row(l + 4));
    // t0 = [r0[0], r1[0], r0[2], r1[2] | r4[0], r5[0], r4[2], r5[2]], and so on
    let [t0, t1, t2, t3] = interleave_pairs([pair(0), pair(1), pair(2), pair(3)]);
    let even = _mm512_setr_epi64(0, 1, 8, 9, 4, 5, 12, 13);
    let odd = _mm512_setr_epi64(2, 3, 10, 11, 6, 7, 14, 15);
    [
        _mm512_permutex2var_pd(t0, even, t2),
        _mm512_permutex2var_pd(t1, even, t3),
        _mm512_permutex2var_pd(t0, odd, t2),
        _mm512_permutex2var_pd(t1, odd, t3),
    ]
}

/// The in-lane unpacks both transposes start with: `[lo(a, b), hi(a, b), lo(c, d), hi(c, d)]`
/// (`lo(a, b)` = a[0], b[0], a[2], b[2], … across the register).
///
/// # Safety
/// AVX-512F must be present.
#[inline(always)]
unsafe fn interleave_pairs([a, b, c, d]: [__m512d; 4]) -> [__m512d; 4] {
    [
        _mm512_unpacklo_pd(a, b),
        _mm512_unpackhi_pd(a, b),
        _mm512_unpacklo_pd(c, d),
        _mm512_unpackhi_pd(c, d),
    ]
}

macro_rules! lane_wise {
    ($trait:ident, $method:ident, $intrinsic:ident) => {
        impl $trait for F64x8 {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                // SAFETY: see the type's documentation
                Self(unsafe { $intrinsic(self.0, o.0) })
            }
        }
    };
}
lane_wise!(Add, add, _mm512_add_pd);
lane_wise!(Sub, sub, _mm512_sub_pd);
lane_wise!(Mul, mul, _mm512_mul_pd);
lane_wise!(Div, div, _mm512_div_pd);

impl Neg for F64x8 {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        // flipping the sign bit is exactly IEEE negation, as for f64 (an integer xor:
        // the f64 xor of AVX-512 needs the DQ extension)
        // SAFETY: see the type's documentation
        unsafe {
            let sign = _mm512_set1_epi64(i64::MIN);
            Self(_mm512_castsi512_pd(_mm512_xor_si512(
                _mm512_castpd_si512(self.0),
                sign,
            )))
        }
    }
}
