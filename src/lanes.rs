//! f64 arithmetic on one element or on four or eight elements at once.
//!
//! The element laws are written once, generic over [`Lanes`]: with `f64` they evaluate one
//! element, with [`F64x4`] four elements side by side in one AVX register per quantity and
//! with [`F64x8`] eight in one AVX-512 register, each lane holding one element's value.
//! The lane operations are plain IEEE arithmetic, with fused multiply–adds only where the
//! code asks for one ([`Lanes::mul_add`], correctly rounded on every path) and no
//! reassociation, so every lane computes bit for bit what the `f64` code computes for
//! that element: the vector kernel changes the speed, never the result. (On x86-64 the
//! one-lane build assumes no FMA instruction, so there `f64::mul_add` calls the C
//! library's `fma`: exact but slower. That build is the fallback for CPUs without AVX2
//! and FMA; the vector builds' scalar tails are compiled with FMA.)
//!
//! The element data reach the lanes ([`Lanes::gather_corners`], [`Lanes::gather_records`])
//! not by scalar loads and inserts, which took a third of the kernel's time and all of it
//! on the shuffle port the arithmetic also needs (docs/BENCHMARKS.md, session 27), and not
//! by hardware gathers (`vgatherdpd`), which on AMD cores cost more than the loads they
//! stand for, but by row loads and a transpose: one row of four f64 per element and
//! quantity block, turned into columns by unpacks and permutes (4×4 on four lanes, 8×4 on
//! eight). This made the AVX2 kernel 1.9× faster on AMD (session 29) and the AVX-512 one
//! 1.4–2× faster there (session 31).

use std::ops::{Add, Div, IndexMut, Mul, Neg, Sub};

/// A value per lane: `f64` (one lane), [`F64x4`] (four) or [`F64x8`] (eight).
pub trait Lanes:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Number of lanes (1, 4 or 8).
    const WIDTH: usize;
    /// One value per lane, `[f64; WIDTH]`.
    type Array: Copy + Default + IndexMut<usize, Output = f64>;
    /// The same constant in every lane.
    fn splat(v: f64) -> Self;
    /// Lanes from one value per lane.
    fn from_array(v: Self::Array) -> Self;
    /// The lanes as one value per lane.
    fn to_array(self) -> Self::Array;
    /// Correctly rounded square root, per lane.
    fn sqrt(self) -> Self;
    /// `self · a + b` rounded once (fused multiply–add), per lane: the same bits on every
    /// path (`f64::mul_add` is the correctly rounded FMA too).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// Per lane: `then` where `self > 0`, else `otherwise` (NaN is not > 0).
    fn where_positive(self, then: Self, otherwise: Self) -> Self;
    /// Whether every lane is > 0 (NaN is not).
    #[inline(always)]
    fn all_positive(self) -> bool {
        let v = self.to_array();
        (0..Self::WIDTH).all(|l| v[l] > 0.0)
    }
    /// Whether every lane is finite.
    #[inline(always)]
    fn all_finite(self) -> bool {
        let v = self.to_array();
        (0..Self::WIDTH).all(|l| v[l].is_finite())
    }

    /// Adds lane `l`'s `nodal[a]` into `force[n]` for node n = `tets[first + l][a]`, lane
    /// after lane and corner after corner: the order of the one-element loop, so every
    /// node's sum is bitwise the same.
    ///
    /// # Safety
    /// `force` points to at least as many entries as the positions `tets` was checked
    /// against, and no other thread accesses the entries these elements add to.
    #[inline(always)]
    unsafe fn add_corner_forces(
        nodal: &[[Self; 3]; 4],
        tets: &TetNodes,
        first: usize,
        force: *mut [f64; 3],
    ) {
        let tets = &tets.tets[first..first + Self::WIDTH];
        let nodal: [[Self::Array; 3]; 4] = build([Self::Array::default(); 3], |a| {
            build(Self::Array::default(), |i| nodal[a][i].to_array())
        });
        for (l, t) in tets.iter().enumerate() {
            for (a, &n) in t.iter().enumerate() {
                let out = &mut *force.add(n as usize);
                out[0] += nodal[a][0][l];
                out[1] += nodal[a][1][l];
                out[2] += nodal[a][2][l];
            }
        }
    }

    /// The corner positions of tetrahedra `first..first + WIDTH` of `tets`, one per
    /// lane: lane `l` of `[a][i]` is `x[tets[first + l][a]][i]`.
    #[inline(always)]
    fn gather_corners(tets: &TetNodes, first: usize) -> [[Self; 3]; 4] {
        let (x, tets) = (tets.x, &tets.tets[first..first + Self::WIDTH]);
        let mut corners = [[Self::splat(0.0); 3]; 4];
        for (a, corner) in corners.iter_mut().enumerate() {
            for (i, c) in corner.iter_mut().enumerate() {
                *c = gather(|l| x[tets[l][a] as usize][i]);
            }
        }
        corners
    }

    /// The first `WIDTH` records of `records`, one per lane: lane `l` of `[k]` is
    /// `records[l][k]`.
    fn gather_records<const N: usize>(records: &[[f64; N]]) -> [Self; N];
}

impl Lanes for f64 {
    const WIDTH: usize = 1;
    type Array = [f64; 1];
    #[inline(always)]
    fn splat(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn from_array(v: [f64; 1]) -> Self {
        v[0]
    }
    #[inline(always)]
    fn to_array(self) -> [f64; 1] {
        [self]
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        f64::mul_add(self, a, b)
    }
    #[inline(always)]
    fn where_positive(self, then: Self, otherwise: Self) -> Self {
        if self > 0.0 {
            then
        } else {
            otherwise
        }
    }
    #[inline(always)]
    fn gather_records<const N: usize>(records: &[[f64; N]]) -> [Self; N] {
        records[0]
    }
}

/// `[f(0), f(1), …]`, like `std::array::from_fn` but always inlined: the vector kernel
/// is compiled for AVX2 only where every step of it inlines into the AVX2 function, and
/// `from_fn` and `map` may be left as calls (each lane operation then becomes a call).
#[inline(always)]
pub fn build<T: Copy, const N: usize>(zero: T, mut f: impl FnMut(usize) -> T) -> [T; N] {
    let mut out = [zero; N];
    for (k, v) in out.iter_mut().enumerate() {
        *v = f(k);
    }
    out
}

/// a₀b₀ + a₁b₁ + a₂b₂ by two fused multiply–adds: fewer instructions and roundings than
/// three products and two sums, and the same bits on every path.
#[inline(always)]
pub fn dot3<T: Lanes>(a0: T, b0: T, a1: T, b1: T, a2: T, b2: T) -> T {
    a2.mul_add(b2, a1.mul_add(b1, a0 * b0))
}

/// Hints the cache lines holding `count` values from `start` into L1: a prefetch, so
/// nothing is read, nothing can fault (`start` need not even be valid) and results cannot
/// change.
#[inline(always)]
pub fn prefetch<T>(start: *const T, count: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let start = start.cast::<i8>();
        for offset in (0..count * std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: a prefetch never faults; the address is only computed (wrapping)
            unsafe {
                use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
                _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(offset));
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (start, count);
}

/// Node positions and tetrahedra whose node ids were all checked, once, to be below
/// `x.len()`: the row loads of [`Lanes::gather_corners`] then need no check per load (a
/// check per load, a compare and a conditional move for every corner, was an eighth of
/// the eight-lane kernel's instructions and kept every node id live in a register).
#[derive(Debug, Clone, Copy)]
pub struct TetNodes<'a> {
    x: &'a [[f64; 3]],
    tets: &'a [[u32; 4]],
}

impl<'a> TetNodes<'a> {
    /// Checks every node id of `tets` against `x.len()`.
    pub fn new(x: &'a [[f64; 3]], tets: &'a [[u32; 4]]) -> Self {
        // a plain max over the ids vectorises; it costs a fraction of one element
        let largest = tets.iter().flatten().fold(0u32, |m, &n| m.max(n));
        assert!(
            tets.is_empty() || (largest as usize) < x.len(),
            "node id {largest} beyond the {} positions",
            x.len()
        );
        Self { x, tets }
    }

    /// The positions of the four corners of tetrahedron `k`.
    #[inline(always)]
    pub fn corners_of(&self, k: usize) -> [[f64; 3]; 4] {
        let t = &self.tets[k];
        // SAFETY: every id was checked against x.len() in `new`
        build([0.0; 3], |a| unsafe {
            *self.x.get_unchecked(t[a] as usize)
        })
    }

    /// Number of tetrahedra.
    pub fn len(&self) -> usize {
        self.tets.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.tets.is_empty()
    }
}

/// One value per lane from `value(lane)`: how the kernel gathers element data into lanes.
#[inline(always)]
pub fn gather<T: Lanes>(mut value: impl FnMut(usize) -> f64) -> T {
    let mut v = T::Array::default();
    for l in 0..T::WIDTH {
        v[l] = value(l);
    }
    T::from_array(v)
}

#[cfg(target_arch = "x86_64")]
pub use avx::F64x4;
#[cfg(target_arch = "x86_64")]
pub use avx512::F64x8;

/// Element data into lanes by row loads and a transpose, for both vector widths: one
/// masked load of four f64 per element (a node's x, y, z, or a block of four fields of a
/// record), turned into one register per quantity by the width's transpose. Not
/// `vgatherdpd`: on AMD cores a gather costs more than the loads it stands for, on four
/// lanes and on eight (docs/BENCHMARKS.md, sessions 29 and 31); the values, and so the
/// results, are the same.
#[cfg(target_arch = "x86_64")]
mod rows {
    use super::{Lanes, TetNodes};
    use std::arch::x86_64::*;

    /// A register of `ROWS` f64 lanes.
    pub(super) trait Transpose: Copy {
        const ROWS: usize;
        /// `[c0, c1, c2, c3]` with lane l of c_k equal to lane k of `row(l)`, l < `ROWS`.
        ///
        /// # Safety
        /// The CPU must support the register's instruction set.
        unsafe fn columns(row: impl Fn(usize) -> __m256d) -> [Self; 4];
    }

    /// [`Lanes::gather_corners`] for lanes `L` wrapping registers `V`.
    ///
    /// # Safety
    /// The CPU must support AVX and `V`'s instruction set.
    #[inline(always)]
    pub(super) unsafe fn corners<V: Transpose, L: Lanes>(
        nodes: &TetNodes,
        first: usize,
        wrap: impl Fn(V) -> L,
    ) -> [[L; 3]; 4] {
        let tets = &nodes.tets[first..first + V::ROWS];
        let x = nodes.x.as_ptr();
        let mut corners = [[L::splat(0.0); 3]; 4];
        // each row reads the three f64 of x[n] only (the mask drops the fourth), and every
        // n < x.len() was checked by `TetNodes::new`
        let xyz = _mm256_setr_epi64x(-1, -1, -1, 0);
        for (a, corner) in corners.iter_mut().enumerate() {
            let [cx, cy, cz, _] =
                V::columns(|l| _mm256_maskload_pd(x.add(tets[l][a] as usize) as *const f64, xyz));
            *corner = [wrap(cx), wrap(cy), wrap(cz)];
        }
        corners
    }

    /// [`Lanes::gather_records`] for lanes `L` wrapping registers `V`.
    ///
    /// # Safety
    /// As [`corners`].
    #[inline(always)]
    pub(super) unsafe fn records<V: Transpose, L: Lanes, const N: usize>(
        records: &[[f64; N]],
        wrap: impl Fn(V) -> L,
    ) -> [L; N] {
        assert!(records.len() >= V::ROWS);
        let mut out = [L::splat(0.0); N];
        for j in 0..N.div_ceil(4) {
            // row l of block j reads records[l][4j..min(4j + 4, N)] only (the mask drops
            // fields ≥ N)
            let fields = (N - 4 * j).min(4);
            let mask = _mm256_setr_epi64x(
                -1,
                if fields > 1 { -1 } else { 0 },
                if fields > 2 { -1 } else { 0 },
                if fields > 3 { -1 } else { 0 },
            );
            let columns = V::columns(|l| {
                let p = (records.as_ptr().add(l) as *const f64).add(4 * j);
                if fields == 4 {
                    _mm256_loadu_pd(p)
                } else {
                    _mm256_maskload_pd(p, mask)
                }
            });
            for (k, c) in columns.into_iter().take(fields).enumerate() {
                out[4 * j + k] = wrap(c);
            }
        }
        out
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
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
    }

    impl Transpose for __m256d {
        const ROWS: usize = 4;
        #[inline(always)]
        unsafe fn columns(row: impl Fn(usize) -> __m256d) -> [Self; 4] {
            transpose4([row(0), row(1), row(2), row(3)])
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
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::rows::{self, Transpose};
    use super::{Lanes, TetNodes};
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
            force: *mut [f64; 3],
        ) {
            let tets = &tets.tets[first..first + 8];
            // Node a's (x, y) of elements 0, 2, 4, 6 in `even[a]` and of 1, 3, 5, 7 in
            // `odd[a]`, a 128-bit pair each; z stays in its column. Every element and
            // corner is written out (no loop, no array indexed by a variable), so that
            // nothing goes through the stack: a row stored as 256 bits and read back as a
            // scalar stalled store forwarding.
            let mut even = [_mm512_setzero_pd(); 4];
            let mut odd = [_mm512_setzero_pd(); 4];
            let mut z = [_mm512_setzero_pd(); 4];
            for a in 0..4 {
                even[a] = _mm512_unpacklo_pd(nodal[a][0].0, nodal[a][1].0);
                odd[a] = _mm512_unpackhi_pd(nodal[a][0].0, nodal[a][1].0);
                z[a] = nodal[a][2].0;
            }
            macro_rules! corner {
                ($l:literal, $pairs:ident, $q:literal, $a:literal) => {
                    let p = force.add(tets[$l][$a] as usize) as *mut f64;
                    let xy = _mm512_extractf32x4_ps::<$q>(_mm512_castpd_ps($pairs[$a]));
                    let sum = _mm_add_pd(_mm_loadu_pd(p), _mm_castps_pd(xy));
                    _mm_storeu_pd(p, sum);
                    let lane = _mm512_castpd_si512(z[$a]);
                    let zl = _mm512_castpd512_pd128(_mm512_castsi512_pd(
                        _mm512_alignr_epi64::<$l>(lane, lane),
                    ));
                    _mm_store_sd(p.add(2), _mm_add_sd(_mm_load_sd(p.add(2)), zl));
                };
            }
            macro_rules! element {
                ($l:literal, $pairs:ident, $q:literal) => {
                    corner!($l, $pairs, $q, 0);
                    corner!($l, $pairs, $q, 1);
                    corner!($l, $pairs, $q, 2);
                    corner!($l, $pairs, $q, 3);
                };
            }
            element!(0, even, 0);
            element!(1, odd, 0);
            element!(2, even, 1);
            element!(3, odd, 1);
            element!(4, even, 2);
            element!(5, odd, 2);
            element!(6, even, 3);
            element!(7, odd, 3);
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
    }

    impl Transpose for __m512d {
        const ROWS: usize = 8;
        #[inline(always)]
        unsafe fn columns(row: impl Fn(usize) -> __m256d) -> [Self; 4] {
            transpose8x4(row)
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
        let [z0, z1, z2, z3] = [pair(0), pair(1), pair(2), pair(3)];
        // t0 = [r0[0], r1[0], r0[2], r1[2] | r4[0], r5[0], r4[2], r5[2]], and so on
        let t0 = _mm512_unpacklo_pd(z0, z1);
        let t1 = _mm512_unpackhi_pd(z0, z1);
        let t2 = _mm512_unpacklo_pd(z2, z3);
        let t3 = _mm512_unpackhi_pd(z2, z3);
        let even = _mm512_setr_epi64(0, 1, 8, 9, 4, 5, 12, 13);
        let odd = _mm512_setr_epi64(2, 3, 10, 11, 6, 7, 14, 15);
        [
            _mm512_permutex2var_pd(t0, even, t2),
            _mm512_permutex2var_pd(t1, even, t3),
            _mm512_permutex2var_pd(t0, odd, t2),
            _mm512_permutex2var_pd(t1, odd, t3),
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
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    /// Each lane of `T` computes bit for bit what `f64` computes.
    fn lanes_compute_what_scalars_compute<T: Lanes>() {
        let xs = [1.0, -2.5, 3.0e-7, 1.0 / 3.0, 5.5e3, -0.0, 7.25, 1e-300];
        let ys = [0.1, 7.0, -1.0e9, 2.0 / 3.0, -3.0, 2.0, 7.25, 3.0];
        let (a, b): (T, T) = (gather(|l| xs[l]), gather(|l| ys[l]));
        let r = ((a * b + a - b) * -a / b).sqrt().to_array();
        let chosen = (a - b).where_positive(a, b).to_array();
        let nan = T::splat(f64::NAN).where_positive(a, b).to_array();
        let negated_zero = (-T::splat(0.0)).to_array();
        for l in 0..T::WIDTH {
            let (x, y) = (xs[l], ys[l]);
            assert_eq!(r[l].to_bits(), ((x * y + x - y) * -x / y).sqrt().to_bits());
            assert_eq!(chosen[l], (x - y).where_positive(x, y));
            assert_eq!(nan[l], y, "NaN is not positive");
            assert_eq!(negated_zero[l].to_bits(), (-0.0f64).to_bits());
            assert_eq!(T::splat(2.0).to_array()[l], 2.0);
        }
        // the kernel's loads: corner positions by node id, and records of ten f64
        let x: Vec<[f64; 3]> = (0..50)
            .map(|n| [n as f64, 0.5 - n as f64, 1e-3 * n as f64])
            .collect();
        let tets: Vec<[u32; 4]> = (0..8)
            .map(|e| [7 * e, 49 - 5 * e, 3 + e, 6 * e + 1])
            .collect();
        let records: Vec<[f64; 10]> = (0..8)
            .map(|e| build(0.0, |k| (10 * e + k) as f64 + 0.25))
            .collect();
        let corners = T::gather_corners(&TetNodes::new(&x, &tets), 0);
        let fields: [T; 10] = T::gather_records(&records);
        for l in 0..T::WIDTH {
            for a in 0..4 {
                for i in 0..3 {
                    let want = x[tets[l][a] as usize][i];
                    assert_eq!(
                        corners[a][i].to_array()[l],
                        want,
                        "corner {a}, component {i}"
                    );
                }
            }
            for (k, field) in fields.iter().enumerate() {
                assert_eq!(field.to_array()[l], records[l][k], "record field {k}");
            }
        }
        // forces added into the nodes in the order of the one-element loop: lane after
        // lane, corner after corner (nodes shared between lanes, and node 7 twice in lane 1)
        let nodal: [[T; 3]; 4] = build([T::splat(0.0); 3], |a| {
            build(T::splat(0.0), |i| {
                gather(|l| ((a * 3 + i) as f64 + 0.1) / (l as f64 + 3.0))
            })
        });
        let mut added = vec![[1.0 / 3.0; 3]; x.len()];
        let mut expected = added.clone();
        let nodes = TetNodes::new(&x, &tets);
        // SAFETY: `added` has one entry per position; nothing else touches it
        unsafe { T::add_corner_forces(&nodal, &nodes, 0, added.as_mut_ptr()) };
        for (l, t) in tets.iter().take(T::WIDTH).enumerate() {
            for (a, &n) in t.iter().enumerate() {
                for i in 0..3 {
                    expected[n as usize][i] += nodal[a][i].to_array()[l];
                }
            }
        }
        for (n, (got, want)) in added.iter().zip(&expected).enumerate() {
            for i in 0..3 {
                assert_eq!(
                    got[i].to_bits(),
                    want[i].to_bits(),
                    "node {n}, component {i}"
                );
            }
        }
        // records whose length is not a multiple of four (the J2 state has seven fields):
        // the last block of each is a partial row
        let states: Vec<[f64; 7]> = (0..8)
            .map(|e| build(0.0, |k| -((7 * e + k) as f64) - 0.5))
            .collect();
        let fields: [T; 7] = T::gather_records(&states[..T::WIDTH]);
        for l in 0..T::WIDTH {
            for (k, field) in fields.iter().enumerate() {
                assert_eq!(field.to_array()[l], states[l][k], "state field {k}");
            }
        }
    }

    /// A node id beyond the positions stops the gather (an index check, not a stray read).
    fn a_node_id_beyond_the_positions_panics<T: Lanes>() {
        let x = vec![[0.0; 3]; 10];
        let mut tets = vec![[0u32, 1, 2, 3]; 8];
        tets[T::WIDTH - 1][2] = 10;
        let outcome = std::panic::catch_unwind(|| T::gather_corners(&TetNodes::new(&x, &tets), 0));
        assert!(outcome.is_err(), "node 10 of 10 positions was gathered");
    }

    #[test]
    fn avx2_lanes_compute_what_scalars_compute() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            panic!("this test needs an AVX2 CPU: the kernel's fast path could not be checked");
        }
        lanes_compute_what_scalars_compute::<F64x4>();
        a_node_id_beyond_the_positions_panics::<F64x4>();
        a_node_id_beyond_the_positions_panics::<f64>();
    }

    #[test]
    fn avx512_lanes_compute_what_scalars_compute() {
        if !(std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl"))
        {
            println!("no AVX-512F and VL on this CPU: the eight-lane path is never taken here");
            return;
        }
        lanes_compute_what_scalars_compute::<F64x8>();
        a_node_id_beyond_the_positions_panics::<F64x8>();
    }
}
