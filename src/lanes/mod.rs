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

use std::ops::{Add, Div, Index, IndexMut, Mul, Neg, Range, Sub};

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
    /// `b − self · a` rounded once, per lane: bitwise `(−self).mul_add(a, b)` (negation is
    /// exact), in one instruction on the vector paths.
    #[inline(always)]
    fn neg_mul_add(self, a: Self, b: Self) -> Self {
        (-self).mul_add(a, b)
    }
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
        force: *mut NodeForce,
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
    /// Fields stored lane-blocked (`rows[k][l]`: field k of element l of a block of eight,
    /// see `element::references`): field k of elements `lane0..lane0 + WIDTH` into lane
    /// k of the result, one row load each. `lane0` is a multiple of `WIDTH`.
    fn load_rows<const N: usize>(rows: &[[f64; 8]; N], lane0: usize) -> [Self; N];
    /// The inverse of [`Lanes::gather_records`]: lane l of `values[k]` into
    /// `records[l][k]`, for the first `WIDTH` records.
    #[inline(always)]
    fn scatter_records<const N: usize>(values: &[Self; N], records: &mut [[f64; N]]) {
        let records = &mut records[..Self::WIDTH];
        for (k, v) in values.iter().enumerate() {
            let v = v.to_array();
            for (l, record) in records.iter_mut().enumerate() {
                record[k] = v[l];
            }
        }
    }
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
    #[inline(always)]
    fn load_rows<const N: usize>(rows: &[[f64; 8]; N], lane0: usize) -> [Self; N] {
        build(0.0, |k| rows[k][lane0])
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
    prefetch_lines::<T, true>(start, count);
}

/// [`prefetch`] into L2 only: for data needed after the work in hand, which keeps L1 for
/// itself.
#[inline(always)]
pub fn prefetch_to_l2<T>(start: *const T, count: usize) {
    prefetch_lines::<T, false>(start, count);
}

#[inline(always)]
fn prefetch_lines<T, const TO_L1: bool>(start: *const T, count: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0, _MM_HINT_T1};
        let start = start.cast::<i8>();
        for offset in (0..count * std::mem::size_of::<T>()).step_by(64) {
            let line = start.wrapping_add(offset);
            // SAFETY: a prefetch never faults; the address is only computed (wrapping)
            unsafe {
                if TO_L1 {
                    _mm_prefetch::<_MM_HINT_T0>(line);
                } else {
                    _mm_prefetch::<_MM_HINT_T1>(line);
                }
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (start, count);
}

/// Hints both lines `array[n]` may straddle (a node's 24-byte vector does, one in four);
/// nothing past the end.
#[inline(always)]
pub fn touch_value<T>(array: &[T], n: usize) {
    if let Some(value) = array.get(n) {
        touch_pointee(value);
    }
}

/// Hints both lines the value at `p` may straddle, or its one line when its alignment
/// keeps it inside one (a [`NodeForce`]): a prefetch, so `p` is only computed and need
/// not be valid.
#[inline(always)]
pub fn touch_pointee<T>(p: *const T) {
    let p = p.cast::<u8>();
    prefetch(p, 1);
    if std::mem::size_of::<T>() > std::mem::align_of::<T>() {
        prefetch(p.wrapping_add(std::mem::size_of::<T>() - 1), 1);
    }
}

/// A node's force (N): x, y, z, and a fourth f64 that stays 0 so that each node is 32
/// bytes, aligned on 32 bytes. The eight-lane kernel then adds a corner's force into its
/// node with one 256-bit load–add–store inside one cache line, where x, y, z took a pair,
/// a scalar and their shuffles (6–10 % of the in-cache kernel on Zen 5, docs/BENCHMARKS.md,
/// session 66). Indexed 0..3 like `[f64; 3]`; every addition is the same IEEE addition
/// in the same order, so results keep their bits.
#[repr(C, align(32))]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NodeForce([f64; 4]);

impl NodeForce {
    /// No force.
    pub const ZERO: Self = Self([0.0; 4]);

    /// The force (x, y, z).
    #[inline(always)]
    pub fn xyz(&self) -> [f64; 3] {
        [self.0[0], self.0[1], self.0[2]]
    }

    /// x, y, z and the padding (0), for a reader that loads the whole 32 bytes: the
    /// vectorised node update, where three f64 of each node became masked loads that
    /// stalled (docs/BENCHMARKS.md, session 66).
    #[inline(always)]
    pub fn padded(&self) -> [f64; 4] {
        self.0
    }
}

impl From<[f64; 3]> for NodeForce {
    #[inline(always)]
    fn from(f: [f64; 3]) -> Self {
        Self([f[0], f[1], f[2], 0.0])
    }
}

impl Index<usize> for NodeForce {
    type Output = f64;
    #[inline(always)]
    fn index(&self, i: usize) -> &f64 {
        &self.0[..3][i]
    }
}

impl IndexMut<usize> for NodeForce {
    #[inline(always)]
    fn index_mut(&mut self, i: usize) -> &mut f64 {
        &mut self.0[..3][i]
    }
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
    /// Tetrahedra `range` of `tets`, whose ids were bounded once when `tets` was built:
    /// one comparison against `x.len()`. Reading a chunk's ids before its loop to check
    /// them was 4–5 % of the kernel's time on a mesh beyond L2 (docs/BENCHMARKS.md,
    /// session 74).
    pub fn of(x: &'a [[f64; 3]], tets: &'a Connectivity, range: Range<usize>) -> Self {
        assert!(
            tets.node_bound() <= x.len(),
            "node id {} beyond the {} positions",
            tets.node_bound().saturating_sub(1),
            x.len()
        );
        Self {
            x,
            tets: &tets[range],
        }
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

/// Tetrahedra as four node ids each, with the bound on their ids found once, when they
/// are built: [`TetNodes::of`] then checks a pass's positions with one comparison. There
/// is no mutable access to the ids, so the bound stays true.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Connectivity {
    ids: Vec<[u32; 4]>,
    /// One more than the largest id (0 without tetrahedra).
    bound: usize,
}

impl Connectivity {
    pub fn new(ids: Vec<[u32; 4]>) -> Self {
        let bound = ids.iter().flatten().max().map_or(0, |&n| n as usize + 1);
        Self { ids, bound }
    }

    /// One more than the largest node id (0 without tetrahedra).
    pub fn node_bound(&self) -> usize {
        self.bound
    }
}

impl From<Vec<[u32; 4]>> for Connectivity {
    fn from(ids: Vec<[u32; 4]>) -> Self {
        Self::new(ids)
    }
}

impl std::ops::Deref for Connectivity {
    type Target = [[u32; 4]];
    fn deref(&self) -> &[[u32; 4]] {
        &self.ids
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

#[cfg(target_arch = "x86_64")]
mod rows;

#[cfg(target_arch = "x86_64")]
mod avx;

#[cfg(target_arch = "x86_64")]
mod avx512;

#[cfg(all(test, target_arch = "x86_64"))]
mod tests;
