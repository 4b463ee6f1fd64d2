//! The reference data of a model's elements, stored for the vector kernel: in blocks of
//! eight elements, field by field.
//!
//! Why: the kernel evaluates four or eight elements at once, one per lane, and needs each
//! field (a Dm⁻¹ entry, V0) of those elements in one register. Stored element by element,
//! the ten fields of eight elements reach the lanes through three 8×4 transposes per group
//! (36 shuffles, on the port the arithmetic needs too). Stored here, field k of eight
//! consecutive elements is one aligned 64-byte row: one load per field, no shuffle, and
//! the rows of a group are contiguous, so the prefetch of a group is one stretch of lines.
//!
//! Blocks start at each grain's first element (a grain's element i is lane i mod 8 of its
//! block i / 8), because the kernel's chunks are cut from each grain's elements in steps of
//! `ELEMENT_CHUNK`, a multiple of eight: every chunk, hence every group of lanes, then
//! starts at a block boundary. A grain whose element count is not a multiple of eight
//! leaves its last block partly unused (at most 7 × 80 B per grain).

use super::TetReference;
use std::ops::Range;

/// Elements per block.
pub const BLOCK: usize = 8;
/// Fields per element: Dm⁻¹ (row-major), then V0.
pub const FIELDS: usize = 10;

/// Field k of the block's element l at `fields[k][l]`; one cache line per field.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub struct ReferenceBlock {
    pub fields: [[f64; BLOCK]; FIELDS],
}

impl ReferenceBlock {
    /// The reference data of the block's element `lane`.
    #[inline]
    pub fn element(&self, lane: usize) -> TetReference {
        let f = &self.fields;
        TetReference {
            dm_inv: std::array::from_fn(|k| f[k][lane]),
            volume: f[9][lane],
        }
    }
}

impl Default for ReferenceBlock {
    fn default() -> Self {
        Self {
            fields: [[0.0; BLOCK]; FIELDS],
        }
    }
}

/// The reference data of every element of a model, blocked by grain (module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TetReferences {
    blocks: Vec<ReferenceBlock>,
    /// First element of each grain, ascending, and the grain's first block.
    grain_first_element: Vec<usize>,
    grain_first_block: Vec<usize>,
    elements: usize,
}

impl TetReferences {
    /// `references` (one per element) of grains whose element ranges `grains` tile them in
    /// order.
    pub fn new(
        references: &[TetReference],
        grains: impl IntoIterator<Item = Range<usize>>,
    ) -> Self {
        let mut out = Self {
            elements: references.len(),
            ..Default::default()
        };
        let mut next = 0;
        for g in grains {
            assert_eq!(g.start, next, "grain element ranges must tile the elements");
            next = g.end;
            out.grain_first_element.push(g.start);
            out.grain_first_block.push(out.blocks.len());
            let blocks = g.len().div_ceil(BLOCK);
            out.blocks
                .resize(out.blocks.len() + blocks, ReferenceBlock::default());
        }
        assert_eq!(
            next,
            references.len(),
            "grain element ranges must tile the elements"
        );
        for (e, r) in references.iter().enumerate() {
            out.set(e, *r);
        }
        out
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.elements
    }

    pub fn is_empty(&self) -> bool {
        self.elements == 0
    }

    /// The block and lane of element `e`.
    #[inline]
    pub fn slot(&self, e: usize) -> (usize, usize) {
        assert!(e < self.elements, "element {e} of {}", self.elements);
        let g = self.grain_first_element.partition_point(|&s| s <= e) - 1;
        let i = e - self.grain_first_element[g];
        (self.grain_first_block[g] + i / BLOCK, i % BLOCK)
    }

    /// The reference data of element `e`.
    pub fn get(&self, e: usize) -> TetReference {
        let (b, l) = self.slot(e);
        self.blocks[b].element(l)
    }

    /// Replaces the reference data of element `e`.
    pub fn set(&mut self, e: usize, r: TetReference) {
        let (b, l) = self.slot(e);
        let f = &mut self.blocks[b].fields;
        for (k, v) in r.dm_inv.into_iter().chain([r.volume]).enumerate() {
            f[k][l] = v;
        }
    }

    /// Every element's reference data, in element order.
    pub fn iter(&self) -> impl Iterator<Item = TetReference> + '_ {
        let grains = self.grain_first_element.len();
        (0..grains).flat_map(move |g| {
            let end = self.grain_first_element.get(g + 1).copied();
            let len = end.unwrap_or(self.elements) - self.grain_first_element[g];
            let first = self.grain_first_block[g];
            (0..len).map(move |i| self.blocks[first + i / BLOCK].element(i % BLOCK))
        })
    }

    /// The blocks, for the kernel: a chunk starting at element `e` starts at lane 0 of
    /// block `slot(e).0`.
    pub fn blocks(&self) -> &[ReferenceBlock] {
        &self.blocks
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_element_reads_back_what_was_stored() {
        let reference = |e: usize| TetReference {
            dm_inv: std::array::from_fn(|k| (10 * e + k) as f64),
            volume: -(e as f64),
        };
        let all: Vec<TetReference> = (0..30).map(reference).collect();
        // grains of 9, 8, 0 and 13 elements: partial blocks, an exact one, an empty grain
        let refs = TetReferences::new(&all, [0..9, 9..17, 17..17, 17..30]);
        assert_eq!(refs.len(), 30);
        assert_eq!(refs.iter().collect::<Vec<_>>(), all);
        assert_eq!(refs.blocks().len(), 2 + 1 + 2);
        // each grain starts a block
        assert_eq!(refs.slot(9), (2, 0));
        assert_eq!(refs.slot(17), (3, 0));
        assert_eq!(refs.slot(26), (4, 1));
        assert_eq!(refs.blocks()[4].fields[9][1], -26.0);
    }
}
