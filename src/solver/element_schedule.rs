//! Which element chunks may run at the same time.
//!
//! The force kernel scatters each element's four nodal forces straight into the node
//! force array (one pass, no per-element force buffer: that buffer was two thirds of the
//! bytes a step moved). Two chunks that share a node must then not run concurrently, so
//! the chunks are coloured: chunks of one colour share no node and may run in parallel,
//! and a chunk runs after the chunks of earlier colours it shares a node with
//! (`super::chunk_order`). Every node therefore receives its element forces in a fixed
//! order — colour by colour, element by element — whatever the number of threads, and 1
//! and N threads give bitwise identical forces.
//!
//! Chunks never span two grains and are cut and coloured from each grain's own elements,
//! so a grain's summation order does not depend on which other grains share its rank:
//! 1, 2 and 3 ranks give the same forces too.
//!
//! Grains share no node, so a grain whose node data stays in a core's cache runs whole as
//! one task, its chunks colour after colour: its positions and forces are then fetched
//! once per pass, not once per colour (a colour-by-colour sweep over a rank of a thousand
//! grains had evicted them between colours). Its nodes receive their forces in the same
//! order as in the colour-by-colour sweep, so the results are the same to the bit, and
//! which grains run whole may depend on the thread count. The chunks of larger grains, and
//! of every grain of a rank with too few grains to keep the threads busy, run in
//! dependency order across threads.

use super::chunk_order::ChunkOrder;
use crate::model::{Model, NONE};
use std::ops::Range;

/// Elements per chunk (at most; a grain's last chunk may be shorter). Fixed, not derived
/// from the thread count, so that results are reproducible. Small enough that a sphere of
/// 10⁵ elements gives each colour enough chunks to balance two threads.
pub const ELEMENT_CHUNK: usize = 512;

/// Grains of at most this many elements may run whole as one task: about 12 000 nodes,
/// whose positions and forces (48 B each, ≈ 0.5 MB) stay in a core's L2 across the
/// grain's colours.
pub const WHOLE_GRAIN_ELEMENTS: usize = 65_536;

/// A grain runs whole only if it holds at most this share of one thread's elements, so
/// that the whole-grain tasks balance over the threads.
const WHOLE_GRAIN_SHARE: usize = 4;

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
    /// The chunk's nodes in the order its elements first reach them; none for a grain
    /// that runs whole (the grain before it and its own task fetch its node data).
    pub first_touches: FirstTouches,
    /// Nodes of the next whole grain of the task list whose positions and forces this
    /// chunk hints into L2, spread over its blocks (empty for chunks swept by colour and
    /// for the last whole grain): requested in one burst at that grain's start, they
    /// stalled the force pass (docs/BENCHMARKS.md, session 74).
    pub next_grain_nodes: Range<usize>,
}

/// A chunk's nodes in the order its elements first reach them, so that the force pass can
/// request each one's position and force a few element groups before its first use, once:
/// a chunk of a grain swept colour by colour finds its nodes out of cache (the colours in
/// between evicted them; docs/BENCHMARKS.md, session 41). About half a node per element
/// (a node on a chunk's border is listed by every chunk that reaches it), 4 B each, and
/// 2 B per block of eight elements.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FirstTouches {
    /// Node ids, in the order of first use.
    pub nodes: Vec<u32>,
    /// `nodes[..block_end[b]]` are first used by the chunk's elements below 8(b + 1).
    pub block_end: Vec<u16>,
}

/// Elements per entry of [`FirstTouches::block_end`] (a reference block's).
pub const TOUCH_BLOCK: usize = crate::element::references::BLOCK;

impl FirstTouches {
    /// Of the elements `elements` of `tets`; `stamp` holds, per node, the last chunk that
    /// reached it (`chunk` is this one's number, different from every earlier one's).
    fn new(tets: &[[u32; 4]], elements: Range<usize>, stamp: &mut [u32], chunk: u32) -> Self {
        let mut out = Self::default();
        for block in tets[elements].chunks(TOUCH_BLOCK) {
            for &n in block.iter().flatten() {
                if stamp[n as usize] != chunk {
                    stamp[n as usize] = chunk;
                    out.nodes.push(n);
                }
            }
            let end = u16::try_from(out.nodes.len()).expect("a chunk reaches < 2¹⁶ nodes");
            out.block_end.push(end);
        }
        out
    }
}

/// Chunks of the owned elements, grouped by colour.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElementSchedule {
    /// Ordered by colour, then by first element.
    pub chunks: Vec<ElementChunk>,
    /// `chunks[colours[c]]` are the chunks of colour c: they share no node.
    pub colours: Vec<Range<usize>>,
    /// The tasks of a force pass: first each small grain whole, then the chunks of the
    /// large grains colour by colour. Entries are indices into `chunks`.
    pub tasks: ScheduleTasks,
}

/// How the chunks of a [`ElementSchedule`] are run: small grains whole, one task each
/// (their chunks in colour order), then large grains colour by colour.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScheduleTasks {
    /// `whole_chunks[whole_grains[g]]`: the chunks of small grain g, in colour order.
    pub whole_grains: Vec<Range<usize>>,
    pub whole_chunks: Vec<usize>,
    /// The nodes of small grain g: its task zeroes their forces, while they are in cache.
    pub whole_nodes: Vec<Range<usize>>,
    /// The other nodes (of large grains, ghosts, images), whose forces the pass zeroes
    /// before its tasks.
    pub zeroed_before: Vec<Range<usize>>,
    /// `large_chunks[large_colours[c]]`: the chunks of large grains of one colour.
    pub large_colours: Vec<Range<usize>>,
    pub large_chunks: Vec<usize>,
    /// Which large chunks (positions in `large_chunks`) wait for which: each for those of
    /// earlier colours it shares a node with.
    pub large_order: ChunkOrder,
}

impl ScheduleTasks {
    /// Splits the colour-ordered `chunks` between whole-grain tasks (grains of at most
    /// `whole_limit` elements) and colour sweeps.
    fn new(
        model: &Model,
        chunks: &[ElementChunk],
        colours: &[Range<usize>],
        whole_limit: usize,
    ) -> Self {
        let grain_of = |k: usize| model.grain_of_element(chunks[k].elements.start);
        let is_small = |g: usize| model.grains[g].elements.len() <= whole_limit;
        let mut tasks = Self::default();
        // a grain's chunks, taken in schedule order, are in colour order
        let mut of_grain: Vec<Vec<usize>> = vec![Vec::new(); model.owned_grains];
        for k in 0..chunks.len() {
            if is_small(grain_of(k)) {
                of_grain[grain_of(k)].push(k);
            }
        }
        for (g, ks) in of_grain.iter().enumerate().filter(|(_, ks)| !ks.is_empty()) {
            let start = tasks.whole_chunks.len();
            tasks.whole_chunks.extend(ks);
            tasks.whole_grains.push(start..tasks.whole_chunks.len());
            tasks.whole_nodes.push(model.grains[g].nodes.clone());
        }
        let mut whole_nodes = tasks.whole_nodes.clone();
        whole_nodes.sort_by_key(|r| r.start);
        let mut next = 0;
        for r in whole_nodes
            .iter()
            .chain([&(model.num_nodes()..model.num_nodes())])
        {
            if r.start > next {
                tasks.zeroed_before.push(next..r.start);
            }
            next = next.max(r.end);
        }
        for colour in colours {
            let start = tasks.large_chunks.len();
            tasks
                .large_chunks
                .extend(colour.clone().filter(|&k| !is_small(grain_of(k))));
            if tasks.large_chunks.len() > start {
                tasks.large_colours.push(start..tasks.large_chunks.len());
            }
        }
        tasks
    }
}

impl ElementSchedule {
    /// The schedule of `model`'s owned elements for the current rayon pool.
    pub fn new(model: &Model) -> Self {
        let per_thread = model.owned_elements / rayon::current_num_threads().max(1);
        Self::with_whole_limit(
            model,
            WHOLE_GRAIN_ELEMENTS.min(per_thread / WHOLE_GRAIN_SHARE),
        )
    }

    /// The schedule with grains of at most `whole_limit` elements run whole.
    pub fn with_whole_limit(model: &Model, whole_limit: usize) -> Self {
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
                        first_touches: FirstTouches::default(),
                        next_grain_nodes: 0..0,
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
        let mut chunks: Vec<ElementChunk> = coloured.into_iter().map(|(_, chunk)| chunk).collect();
        let mut tasks = ScheduleTasks::new(model, &chunks, &colours, whole_limit);
        // only chunks swept colour by colour: a whole grain's task brings all its
        // positions and forces into cache first
        let mut stamp = vec![u32::MAX; model.num_nodes()];
        for &k in &tasks.large_chunks {
            let chunk = &mut chunks[k];
            let number = u32::try_from(k).expect("< 2³² chunks");
            chunk.first_touches =
                FirstTouches::new(&model.tets, chunk.elements.clone(), &mut stamp, number);
        }
        for (i, grain) in tasks.whole_grains.iter().enumerate() {
            let Some(next) = tasks.whole_nodes.get(i + 1) else {
                break;
            };
            // in proportion to the chunks' elements, so the hints follow the work
            let ks = &tasks.whole_chunks[grain.clone()];
            let total: usize = ks.iter().map(|&k| chunks[k].elements.len()).sum();
            let mut done = 0;
            for &k in ks {
                let at = |done: usize| next.start + next.len() * done / total.max(1);
                let start = at(done);
                done += chunks[k].elements.len();
                chunks[k].next_grain_nodes = start..at(done);
            }
        }
        // the same lists give each chunk's nodes once, for the order between chunks
        let large = (tasks.large_chunks.iter()).map(|&k| &chunks[k].first_touches.nodes[..]);
        tasks.large_order = ChunkOrder::new(large, model.num_nodes());
        Self {
            chunks,
            colours,
            tasks,
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::scene::parse_scene;
    use crate::solver::build_solver;

    /// The model of glass spheres (x-coordinate of the centre, radius, seeding; m), for
    /// the schedule's tests.
    pub(in crate::solver) fn glass_spheres_model(spheres: &[(f64, f64, f64)]) -> Model {
        let mut text = String::from(
            "[simulation]\nduration = 1e-6\n[materials.glass]\nyoungs_modulus = 63e9\n\
             poisson_ratio = 0.22\ndensity = 2500.0\n",
        );
        for (k, (x, radius, seeding)) in spheres.iter().enumerate() {
            text += &format!(
                "[[grains]]\nname = \"g{k}\"\nmaterial = \"glass\"\ncentre = [{x:e}, 0.0, 0.0]\n\
                 shape = {{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}\n"
            );
        }
        let loaded = parse_scene("element_schedule.toml", &text, &[]).unwrap();
        build_solver(&loaded).unwrap().model
    }

    fn two_sphere_model() -> Model {
        glass_spheres_model(&[(0.0, 1e-3, 1.5e-4), (3e-3, 0.5e-3, 1e-4)])
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

    /// The chunks of each whole grain but the last hint the next grain's nodes, all of
    /// them once, in order and in proportion to their elements; other chunks hint none.
    #[test]
    fn whole_grains_hint_the_next_grains_nodes_once() {
        let model = glass_spheres_model(&[
            (0.0, 1e-3, 2e-4),
            (3e-3, 0.5e-3, 1e-4),
            (6e-3, 0.7e-3, 1.5e-4),
            (9e-3, 1.5e-3, 1.5e-4),
        ]);
        // the first three whole, the largest by colour
        let limit = model.grains[..3].iter().map(|g| g.elements.len()).max();
        let schedule = ElementSchedule::with_whole_limit(&model, limit.unwrap());
        let tasks = &schedule.tasks;
        assert_eq!(tasks.whole_grains.len(), 3);
        for (i, grain) in tasks.whole_grains.iter().enumerate() {
            let ks = &tasks.whole_chunks[grain.clone()];
            assert!(ks.len() > 1, "a grain of several chunks");
            let hinted: Vec<_> = ks.iter().map(|&k| &schedule.chunks[k]).collect();
            let Some(next) = tasks.whole_nodes.get(i + 1) else {
                assert!(hinted.iter().all(|c| c.next_grain_nodes.is_empty()));
                continue;
            };
            let mut at = next.start;
            let elements: usize = hinted.iter().map(|c| c.elements.len()).sum();
            for c in &hinted {
                assert_eq!(c.next_grain_nodes.start, at);
                at = c.next_grain_nodes.end;
                let share = c.elements.len() as f64 / elements as f64;
                let got = c.next_grain_nodes.len() as f64 / next.len() as f64;
                assert!((got - share).abs() <= 1.0 / next.len() as f64 + 1e-12);
            }
            assert_eq!(at, next.end);
        }
        let large = tasks.large_chunks.iter().map(|&k| &schedule.chunks[k]);
        assert!(large.clone().count() > 0);
        assert!(large.into_iter().all(|c| c.next_grain_nodes.is_empty()));
    }

    /// A chunk swept by colour lists each of its nodes once, in the order its elements
    /// first reach them, and each block's end counts the nodes its elements and the earlier
    /// ones reach; a chunk of a grain that runs whole lists none.
    #[test]
    fn first_touches_list_each_node_of_a_chunk_once_in_order_of_first_use() {
        let model = two_sphere_model();
        // the small sphere whole, the large one by colour
        let schedule = ElementSchedule::with_whole_limit(&model, model.grains[1].elements.len());
        assert!(!schedule.tasks.whole_chunks.is_empty());
        for (k, chunk) in schedule.chunks.iter().enumerate() {
            let touches = &chunk.first_touches;
            if schedule.tasks.whole_chunks.contains(&k) {
                assert_eq!(*touches, FirstTouches::default());
                continue;
            }
            let tets = &model.tets[chunk.elements.clone()];
            let mut expected: Vec<u32> = Vec::new();
            let mut block_end = Vec::new();
            for (k, tet) in tets.iter().enumerate() {
                for &n in tet {
                    if !expected.contains(&n) {
                        expected.push(n);
                    }
                }
                if (k + 1) % TOUCH_BLOCK == 0 || k + 1 == tets.len() {
                    block_end.push(expected.len() as u16);
                }
            }
            assert_eq!(touches.nodes, expected);
            assert_eq!(touches.block_end, block_end);
        }
    }

    #[test]
    fn every_chunk_is_one_task_and_a_whole_grain_runs_its_chunks_in_colour_order() {
        let model = two_sphere_model();
        // the small sphere whole, the large one by colour
        let limit = model.grains[1].elements.len();
        assert!(model.grains[0].elements.len() > limit);
        let schedule = ElementSchedule::with_whole_limit(&model, limit);
        // the same chunks and colours whichever grains run whole
        let cut = |s: &ElementSchedule| -> Vec<_> {
            (s.chunks.iter())
                .map(|c| (c.elements.clone(), c.law, c.plastic_start))
                .collect()
        };
        assert_eq!(cut(&schedule), cut(&ElementSchedule::new(&model)));
        let tasks = &schedule.tasks;
        assert!(
            !tasks.whole_grains.is_empty(),
            "the small sphere runs whole"
        );
        assert!(
            !tasks.large_colours.is_empty(),
            "the large sphere is swept by colour"
        );
        let mut seen = vec![0u8; schedule.chunks.len()];
        for &k in tasks.whole_chunks.iter().chain(&tasks.large_chunks) {
            seen[k] += 1;
        }
        assert!(seen.iter().all(|&s| s == 1));
        let mut zeroed = vec![0u8; model.num_nodes()];
        for r in tasks.whole_nodes.iter().chain(&tasks.zeroed_before) {
            r.clone().for_each(|n| zeroed[n] += 1);
        }
        assert!(
            zeroed.iter().all(|&z| z == 1),
            "every node's force zeroed once"
        );
        let colour_of = |k: usize| schedule.colours.iter().position(|c| c.contains(&k));
        for (g, nodes) in tasks.whole_grains.iter().zip(&tasks.whole_nodes) {
            let ks = &tasks.whole_chunks[g.clone()];
            for &k in ks {
                for e in schedule.chunks[k].elements.clone() {
                    assert!(model.tets[e].iter().all(|&n| nodes.contains(&(n as usize))));
                }
            }
        }
        for g in &tasks.whole_grains {
            let ks = &tasks.whole_chunks[g.clone()];
            let grain = model.grain_of_element(schedule.chunks[ks[0]].elements.start);
            assert!(model.grains[grain].elements.len() <= limit);
            // chunks of one grain and one colour share no node: their order is free
            for w in ks.windows(2) {
                assert!(
                    colour_of(w[0]) <= colour_of(w[1]),
                    "colour order within a grain"
                );
            }
            let all_of_grain = (0..schedule.chunks.len())
                .filter(|&k| model.grain_of_element(schedule.chunks[k].elements.start) == grain)
                .count();
            assert_eq!(ks.len(), all_of_grain);
        }
        for c in &tasks.large_colours {
            let colour = colour_of(tasks.large_chunks[c.start]);
            assert!(tasks.large_chunks[c.clone()]
                .iter()
                .all(|&k| colour_of(k) == colour));
        }
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
        alone.tets = alone.tets[shift..]
            .iter()
            .map(|t| t.map(|n| n - nodes.start as u32))
            .collect::<Vec<_>>()
            .into();
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
