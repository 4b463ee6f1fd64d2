//! Four f64 lanes in one AVX register ([`F64x4`]).

use super::rows::{self, Transpose};
use super::{Lanes, TetNodes};
use std::arch::x86_64::*;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Four f64 lanes in one AVX register.
///
/// Every operation executes an AVX instruction: use this type only in code that runs
/// after the CPU has been found to support AVX2 (`solver::forces::KernelPath`), and
/// compiled with that feature enabled, so that the operations inline to single
/// instructions.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct F64x4(__m256d);

impl Lanes for F64x4 {
    const WIDTH: usize = 4;
    type Array = [f64; 4];
    #[inline(always)]
    fn splat(v: f64) -> Self {
        // SAFETY: see the type's documentation (AVX is present where this runs)
        Self(unsafe { _mm256_set1_pd(v) })
    }
    #[inline(always)]
    fn from_array(v: [f64; 4]) -> Self {
        // from registers, not through memory: a wide load of values just stored one
        // by one stalls on store forwarding
        // SAFETY: as `splat`
        Self(unsafe { _mm256_set_pd(v[3], v[2], v[1], v[0]) })
    }
    #[inline(always)]
    fn to_array(self) -> [f64; 4] {
        let mut v = [0.0; 4];
        // SAFETY: as `splat`; the store writes exactly the four values of `v`
        unsafe { _mm256_storeu_pd(v.as_mut_ptr(), self.0) };
        v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        // SAFETY: see the type's documentation
        Self(unsafe { _mm256_sqrt_pd(self.0) })
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        // SAFETY: see the type's documentation (FMA comes with AVX2 where this runs)
        Self(unsafe { _mm256_fmadd_pd(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn neg_mul_add(self, a: Self, b: Self) -> Self {
        // SAFETY: as `mul_add`
        Self(unsafe { _mm256_fnmadd_pd(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn where_positive(self, then: Self, otherwise: Self) -> Self {
        // SAFETY: see the type's documentation
        unsafe {
            let positive = _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, _mm256_setzero_pd());
            Self(_mm256_blendv_pd(otherwise.0, then.0, positive))
        }
    }
    #[inline(always)]
    fn all_positive(self) -> bool {
        // SAFETY: see the type's documentation
        unsafe {
            let positive = _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, _mm256_setzero_pd());
            _mm256_movemask_pd(positive) == 0b1111
        }
    }
    #[inline(always)]
    fn all_finite(self) -> bool {
        // SAFETY: see the type's documentation
        // x − x is 0 for finite x, NaN for ±∞ and NaN
        unsafe {
            let difference = _mm256_sub_pd(self.0, self.0);
            let zero = _mm256_cmp_pd::<_CMP_EQ_OQ>(difference, _mm256_setzero_pd());
            _mm256_movemask_pd(zero) == 0b1111
        }
    }
    // `add_corner_forces`: the trait's, through the stack. Keeping the rows in
    // registers, as eight lanes do, needs more than AVX2's sixteen; the spills made
    // the kernel 0.77× as fast (docs/BENCHMARKS.md, session 32).
    #[inline(always)]
    fn gather_corners(tets: &TetNodes, first: usize) -> [[Self; 3]; 4] {
        // SAFETY: see the type's documentation (AVX2 is present where this runs)
        unsafe { rows::corners::<__m256d, _>(tets, first, Self) }
    }
    #[inline(always)]
    fn gather_records<const N: usize>(records: &[[f64; N]]) -> [Self; N] {
        // SAFETY: as `gather_corners`
        unsafe { rows::records::<__m256d, _, N>(records, Self) }
    }
    #[inline(always)]
    fn load_rows<const N: usize>(rows: &[[f64; 8]; N], lane0: usize) -> [Self; N] {
        assert!(lane0 <= 4);
        // SAFETY: AVX is present (see the type's documentation); lanes lane0..lane0 + 4 of
        // each row exist
        super::build(Self::splat(0.0), |k| unsafe {
            Self(_mm256_loadu_pd(rows[k].as_ptr().add(lane0)))
        })
    }
    #[inline(always)]
    fn scatter_records<const N: usize>(values: &[Self; N], records: &mut [[f64; N]]) {
        // SAFETY: as `gather_corners`
        unsafe { rows::scatter_records::<__m256d, _, N>(values, records, |v| v.0) }
    }
}

impl Transpose for __m256d {
    const ROWS: usize = 4;
    #[inline(always)]
    unsafe fn columns(row: impl Fn(usize) -> __m256d) -> [Self; 4] {
        transpose4([row(0), row(1), row(2), row(3)])
    }
    #[inline(always)]
    unsafe fn rows(columns: [Self; 4], mut row: impl FnMut(usize, __m256d)) {
        // a 4×4 transpose is its own inverse
        for (l, r) in transpose4(columns).into_iter().enumerate() {
            row(l, r);
        }
    }
}

/// Columns of four rows of four f64: `[r0, r1, r2, r3]` → `[c0, c1, c2, c3]` with lane l
/// of c_k equal to lane k of r_l.
///
/// # Safety
/// AVX must be present.
#[inline(always)]
unsafe fn transpose4(r: [__m256d; 4]) -> [__m256d; 4] {
    let t0 = _mm256_unpacklo_pd(r[0], r[1]);
    let t1 = _mm256_unpackhi_pd(r[0], r[1]);
    let t2 = _mm256_unpacklo_pd(r[2], r[3]);
    let t3 = _mm256_unpackhi_pd(r[2], r[3]);
    [
        _mm256_permute2f128_pd::<0x20>(t0, t2),
        _mm256_permute2f128_pd::<0x20>(t1, t3),
        _mm256_permute2f128_pd::<0x31>(t0, t2),
        _mm256_permute2f128_pd::<0x31>(t1, t3),
    ]
}

macro_rules! lane_wise {
    ($trait:ident, $method:ident, $intrinsic:ident) => {
        impl $trait for F64x4 {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                // SAFETY: see the type's documentation
                Self(unsafe { $intrinsic(self.0, o.0) })
            }
        }
    };
}
lane_wise!(Add, add, _mm256_add_pd);
lane_wise!(Sub, sub, _mm256_sub_pd);
lane_wise!(Mul, mul, _mm256_mul_pd);
lane_wise!(Div, div, _mm256_div_pd);

impl Neg for F64x4 {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        // flipping the sign bit is exactly IEEE negation, as for f64
        // SAFETY: see the type's documentation
        Self(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
    }
}
