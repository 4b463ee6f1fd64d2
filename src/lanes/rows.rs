//! Element data into lanes by row loads and a transpose, for both vector widths: one
//! masked load of four f64 per element (a node's x, y, z, or a block of four fields of a
//! record), turned into one register per quantity by the width's transpose. Not
//! `vgatherdpd`: on AMD cores a gather costs more than the loads it stands for, on four
//! lanes and on eight (docs/BENCHMARKS.md, sessions 29 and 31); the values, and so the
//! results, are the same.

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
    /// The inverse: `row(l, r)` for l < `ROWS` with lane k of r equal to lane l of
    /// `columns[k]`.
    ///
    /// # Safety
    /// As [`Transpose::columns`].
    unsafe fn rows(columns: [Self; 4], row: impl FnMut(usize, __m256d));
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
    // n < x.len() was checked by `TetNodes::of`
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
        let mask = block_mask(fields);
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

/// [`Lanes::scatter_records`] for lanes `L` wrapping registers `V`.
///
/// # Safety
/// As [`corners`].
#[inline(always)]
pub(super) unsafe fn scatter_records<V: Transpose, L: Lanes, const N: usize>(
    values: &[L; N],
    records: &mut [[f64; N]],
    unwrap: impl Fn(L) -> V,
) {
    assert!(records.len() >= V::ROWS);
    for j in 0..N.div_ceil(4) {
        // row l of block j writes records[l][4j..min(4j + 4, N)] only
        let fields = (N - 4 * j).min(4);
        let mask = block_mask(fields);
        // a block's columns past the last field are repeats, written nowhere
        let first = unwrap(values[4 * j]);
        let columns: [V; 4] = super::build(first, |k| unwrap(values[(4 * j + k).min(N - 1)]));
        V::rows(columns, |l, row| {
            let p = (records.as_mut_ptr().add(l) as *mut f64).add(4 * j);
            if fields == 4 {
                _mm256_storeu_pd(p, row);
            } else {
                _mm256_maskstore_pd(p, mask, row);
            }
        });
    }
}

/// The mask of the first `fields` of four f64.
#[inline(always)]
unsafe fn block_mask(fields: usize) -> __m256i {
    _mm256_setr_epi64x(
        -1,
        if fields > 1 { -1 } else { 0 },
        if fields > 2 { -1 } else { 0 },
        if fields > 3 { -1 } else { 0 },
    )
}
