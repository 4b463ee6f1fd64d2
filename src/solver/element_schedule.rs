//! Which element chunks may run at the same time.
//!
//! The force kernel scatters each element's four nodal forces straight into the node
//! force array (one pass, no per-element force buffer: that buffer was two thirds of the
//! bytes a step moved). Two chunks that share a node must then not run concurrently, so
//! the chunks are coloured: chunks of one colour share no node and run in parallel, the
//! colours run one after another. Every node therefore receives its element forces in a
//! fixed order — colour by colour, element by element — whatever the number of threads,
//! and 1 and N threads give bitwise identical forces.
//!
//! Chunks never span two grains and are cut and coloured from each grain's own elements,
//! so a grain's summation order does not depend on which other grains share its rank:
//! 1, 2 and 3 ranks give the same forces too.

use crate::model::{Model, NONE};
use std::ops::Range;

/// Elements per chunk (at most; a grain's last chunk may be shorter). Fixed, not derived
/// from the thread count, so that results are reproducible. Small enough that a sphere of
/// 10⁵ elements gives each colour enough chunks to balance two threads.
pub const ELEMENT_CHUNK: usize = 512;

/// Colours a node can remember with one bit each; a chunk that finds them all taken gets
/// a colour of its own (always safe: it then runs alone).
const MASK_COLOURS: usize = 64;

/// A run of consecutive owned elements of one grain.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementChunk {
    pub elements: Range<usize>,
    /// Index into `Model::laws` (one material per grain).
    pub law: u16,
    /// `State::plastic` slot of the first element (elements of plastic materials), whose
    /// slots follow element order.
    pub plastic_start: Option<usize>,
}

/// Chunks of the owned elements, grouped by colour.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElementSchedule {
    /// Ordered by colour, then by first element.
    pub chunks: Vec<ElementChunk>,
    /// `chunks[colours[c]]` are the chunks of colour c: they share no node.
    pub colours: Vec<Range<usize>>,
}

impl ElementSchedule {
    pub fn new(model: &Model) -> Self {
        let mut coloured: Vec<(usize, ElementChunk)> = Vec::new();
        let mut node_colours = vec![0u64; model.owned_nodes];
        let mut own_colours = 0;
        for grain in &model.grains[..model.owned_grains] {
            let elements = grain.elements.clone();
            let law = model.tet_law.get(elements.start).copied().unwrap_or(0);
            for start in elements.clone().step_by(ELEMENT_CHUNK) {
                let range = start..(start + ELEMENT_CHUNK).min(elements.end);
                let nodes = || range.clone().flat_map(|e| model.tets[e]);
                let taken = nodes().fold(0u64, |m, n| m | node_colours[n as usize]);
                let colour = if taken == u64::MAX {
                    // a colour no other chunk uses: numbered after the shared ones, in
                    // chunk order, so the grain's order of colours stays fixed
                    own_colours += 1;
                    MASK_COLOURS + own_colours
                } else {
                    let c = taken.trailing_ones() as usize;
                    nodes().for_each(|n| node_colours[n as usize] |= 1 << c);
                    c
                };
                let plastic_start = model
                    .plastic_slot
                    .get(range.start)
                    .filter(|&&s| s != NONE)
                    .map(|&s| s as usize);
                coloured.push((
                    colour,
                    ElementChunk {
                        elements: range,
                        law,
                        plastic_start,
                    },
                ));
            }
        }
        coloured.sort_by_key(|(colour, chunk)| (*colour, chunk.elements.start));
        let mut colours: Vec<Range<usize>> = Vec::new();
        for (k, (colour, _)) in coloured.iter().enumerate() {
            match colours.last_mut() {
                Some(r) if coloured[r.start].0 == *colour => r.end = k + 1,
                _ => colours.push(k..k + 1),
            }
        }
        Self {
            chunks: coloured.into_iter().map(|(_, chunk)| chunk).collect(),
            colours,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;
    use crate::solver::build_solver;

    fn two_sphere_model() -> Model {
        let text = r#"
[simulation]
duration = 1e-6
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
[[grains]]
name = "a"
material = "glass"
shape = { sphere = { radius = 1e-3, seeding = 1.5e-4 } }
[[grains]]
name = "b"
material = "glass"
centre = [3e-3, 0.0, 0.0]
shape = { sphere = { radius = 0.5e-3, seeding = 1e-4 } }
"#;
        let loaded = parse_scene("element_schedule.toml", text, &[]).unwrap();
        build_solver(&loaded).unwrap().model
    }

    #[test]
    fn chunks_of_one_colour_share_no_node_and_cover_every_element_once() {
        let model = two_sphere_model();
        let schedule = ElementSchedule::new(&model);
        let mut seen = vec![0u8; model.owned_elements];
        for colour in &schedule.colours {
            let mut owner = vec![usize::MAX; model.owned_nodes];
            for (k, chunk) in schedule.chunks[colour.clone()].iter().enumerate() {
                let grain = model.grain_of_element(chunk.elements.start);
                assert_eq!(model.grain_of_element(chunk.elements.end - 1), grain);
                for e in chunk.elements.clone() {
                    seen[e] += 1;
                    for n in model.tets[e] {
                        let o = &mut owner[n as usize];
                        assert!(*o == usize::MAX || *o == k, "node {n} in two chunks");
                        *o = k;
                    }
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
        assert!(schedule.colours.len() > 1);
    }

    #[test]
    fn a_grain_is_scheduled_alike_whatever_shares_its_rank() {
        // the second grain's chunks and colours, alone or after the first grain
        let model = two_sphere_model();
        let both = ElementSchedule::new(&model);
        let mut alone = model.clone();
        let shift = alone.grains[1].elements.start;
        alone.grains.remove(0);
        alone.owned_grains = 1;
        let nodes = alone.grains[0].nodes.clone();
        alone.tets = alone.tets[shift..].to_vec();
        for t in alone.tets.iter_mut() {
            *t = t.map(|n| n - nodes.start as u32);
        }
        alone.tet_law = alone.tet_law[shift..].to_vec();
        alone.owned_elements = alone.tets.len();
        alone.owned_nodes = nodes.len();
        alone.grains[0].elements = 0..alone.tets.len();
        let single = ElementSchedule::new(&alone);
        let of_second = |s: &ElementSchedule, offset: usize| -> Vec<Vec<Range<usize>>> {
            s.colours
                .iter()
                .map(|c| {
                    s.chunks[c.clone()]
                        .iter()
                        .filter(|k| k.elements.start >= offset)
                        .map(|k| k.elements.start - offset..k.elements.end - offset)
                        .collect::<Vec<_>>()
                })
                .filter(|v| !v.is_empty())
                .collect()
        };
        assert_eq!(of_second(&both, shift), of_second(&single, 0));
    }
}
