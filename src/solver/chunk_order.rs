//! The order in which the chunks of the large grains run: each chunk waits only for the
//! chunks of earlier colours it shares a node with, not for whole colours.
//!
//! Colours fix the order in which a node receives its element forces (colour by colour,
//! element by element: `element_schedule`), and that order only constrains chunks that
//! share a node. So a chunk here waits for exactly those of earlier colours, and threads
//! take chunks as they become ready. A colour sweep with a barrier after each colour made a
//! thread wait at every colour's end for the other's last chunk: 7 % of two threads' time
//! on the 1.5·10⁵-tet bench sphere (docs/BENCHMARKS.md, session 42). Every node still
//! receives its forces in colour order, so the forces are bitwise those of the colour
//! sweep, on any number of threads.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering};

/// Which chunks must finish before each chunk of the large grains starts. Chunks are
/// named by their position in the colour-ordered list of large chunks.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChunkOrder {
    /// How many chunks each one waits for.
    pub waits_for: Vec<u32>,
    /// `successors[successor_start[p]..successor_start[p + 1]]` wait for chunk p.
    pub successor_start: Vec<u32>,
    pub successors: Vec<u32>,
}

impl ChunkOrder {
    /// Of the chunks p = 0, 1, … in colour order (chunks of one colour share no node),
    /// given by their nodes, each listed once (their `FirstTouches`), of `num_nodes`.
    pub fn new<'a>(chunks: impl ExactSizeIterator<Item = &'a [u32]>, num_nodes: usize) -> Self {
        let count = chunks.len();
        // a chunk waits for the last earlier chunk at each of its nodes; along a node's
        // chunks these links order them all
        const NONE: u32 = u32::MAX;
        let mut last = vec![NONE; num_nodes];
        let mut links: Vec<(u32, u32)> = Vec::new();
        for (p, nodes) in chunks.enumerate() {
            let p = u32::try_from(p).expect("< 2³² chunks");
            for &n in nodes {
                let at = &mut last[n as usize];
                if *at != NONE {
                    links.push((*at, p));
                }
                *at = p;
            }
        }
        links.sort_unstable();
        links.dedup();
        let mut order = Self {
            waits_for: vec![0; count],
            successor_start: vec![0; count + 1],
            successors: Vec::with_capacity(links.len()),
        };
        for &(before, after) in &links {
            order.waits_for[after as usize] += 1;
            order.successor_start[before as usize + 1] += 1;
            order.successors.push(after);
        }
        for p in 0..count {
            order.successor_start[p + 1] += order.successor_start[p];
        }
        order
    }

    /// The chunks that wait for chunk `p`.
    fn successors_of(&self, p: usize) -> &[u32] {
        let range = self.successor_start[p] as usize..self.successor_start[p + 1] as usize;
        &self.successors[range]
    }
}

/// A [`ChunkOrder`] being run: what each chunk still waits for, and the chunks in the
/// order they became ready. Scratch, allocated once and reset by every run.
#[derive(Debug, Default)]
pub struct ChunkQueue {
    waiting: Vec<AtomicU32>,
    /// Slot i: 1 + the i-th chunk to become ready, 0 until it has.
    ready: Vec<AtomicU32>,
    /// Slots filled, slots claimed by a thread.
    pushed: AtomicUsize,
    claimed: AtomicUsize,
    /// Set when a chunk panicked: the chunks waiting for it will never be ready, so the
    /// other threads stop taking chunks and the panic reaches the caller (not a hang).
    abandoned: AtomicBool,
}

/// Sets its flag if dropped while its thread unwinds from a panic.
struct FlagOnPanic<'a>(&'a AtomicBool);

impl Drop for FlagOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Ordering::Release);
        }
    }
}

/// Polls of a slot not yet filled before a thread yields its core (to the thread that
/// will fill it, if they share one: ranks × threads may exceed the cores).
const SPINS_BEFORE_YIELD: u32 = 64;

impl ChunkQueue {
    /// For the chunks of `order`.
    pub fn new(order: &ChunkOrder) -> Self {
        let count = order.waits_for.len();
        Self {
            waiting: (0..count).map(|_| AtomicU32::new(0)).collect(),
            ready: (0..count).map(|_| AtomicU32::new(0)).collect(),
            pushed: AtomicUsize::new(0),
            claimed: AtomicUsize::new(0),
            abandoned: AtomicBool::new(false),
        }
    }

    /// Runs `run(p)` once for every chunk p of `order`, each after the chunks it waits
    /// for, on every thread of the current pool. A thread only ever waits for a chunk
    /// another thread is running: the order has no cycle (links go from earlier colours
    /// to later ones), so while any chunk is left, one is ready or running, and a lone
    /// thread runs them all.
    pub fn run_all(&self, order: &ChunkOrder, run: impl Fn(usize) + Sync) {
        assert_eq!(self.waiting.len(), order.waits_for.len());
        for ((waiting, &count), slot) in self.waiting.iter().zip(&order.waits_for).zip(&self.ready)
        {
            waiting.store(count, Ordering::Relaxed);
            slot.store(0, Ordering::Relaxed);
        }
        self.pushed.store(0, Ordering::Relaxed);
        self.claimed.store(0, Ordering::Relaxed);
        self.abandoned.store(false, Ordering::Relaxed);
        for (p, &count) in order.waits_for.iter().enumerate() {
            if count == 0 {
                self.push(p);
            }
        }
        let threads = rayon::current_num_threads().min(self.ready.len());
        if threads <= 1 {
            self.take_and_run(order, &run);
        } else {
            use rayon::prelude::*;
            (0..threads)
                .into_par_iter()
                .for_each(|_| self.take_and_run(order, &run));
        }
    }

    /// Claims slots and runs their chunks until every slot is claimed (or a chunk
    /// panicked).
    fn take_and_run(&self, order: &ChunkOrder, run: &impl Fn(usize)) {
        let _flag = FlagOnPanic(&self.abandoned);
        loop {
            let slot = self.claimed.fetch_add(1, Ordering::Relaxed);
            let Some(entry) = self.ready.get(slot) else {
                return;
            };
            let Some(p) = self.wait_until_filled(entry) else {
                return;
            };
            run(p);
            for &s in order.successors_of(p) {
                // the last chunk s waited for makes it ready; its forces are seen by
                // whoever takes s (release here, acquire on the slot)
                if self.waiting[s as usize].fetch_sub(1, Ordering::AcqRel) == 1 {
                    self.push(s as usize);
                }
            }
        }
    }

    fn push(&self, p: usize) {
        let slot = self.pushed.fetch_add(1, Ordering::Relaxed);
        let value = u32::try_from(p + 1).expect("< 2³² chunks");
        self.ready[slot].store(value, Ordering::Release);
    }

    /// The chunk in `entry` once it is filled; `None` if a chunk panicked meanwhile.
    fn wait_until_filled(&self, entry: &AtomicU32) -> Option<usize> {
        let mut polls = 0;
        loop {
            let value = entry.load(Ordering::Acquire);
            if value != 0 {
                return Some(value as usize - 1);
            }
            if self.abandoned.load(Ordering::Acquire) {
                return None;
            }
            if polls < SPINS_BEFORE_YIELD {
                std::hint::spin_loop();
                polls += 1;
            } else {
                std::thread::yield_now();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::element_schedule::tests::glass_spheres_model;
    use crate::solver::element_schedule::ElementSchedule;
    use std::sync::atomic::AtomicU64;

    /// On two threads, many times over: every large chunk runs once; no two chunks that
    /// share a node run at the same time; every node is reached by its chunks in colour
    /// order.
    #[test]
    fn chunks_that_share_a_node_never_overlap_and_reach_it_in_colour_order() {
        let model = glass_spheres_model(&[(0.0, 1e-3, 1e-4)]);
        let schedule = ElementSchedule::with_whole_limit(&model, 0);
        let tasks = &schedule.tasks;
        let order = &tasks.large_order;
        assert!(tasks.large_colours.len() > 3 && tasks.large_chunks.len() > 20);
        assert!(order.waits_for.iter().any(|&w| w > 0));
        let colour_of: Vec<u64> = (0..tasks.large_chunks.len())
            .map(|p| {
                tasks
                    .large_colours
                    .iter()
                    .position(|c| c.contains(&p))
                    .unwrap() as u64
            })
            .collect();
        let nodes_of = |p: usize| {
            let elements = schedule.chunks[tasks.large_chunks[p]].elements.clone();
            let mut nodes: Vec<usize> = model.tets[elements]
                .iter()
                .flatten()
                .map(|&n| n as usize)
                .collect();
            nodes.sort_unstable();
            nodes.dedup();
            nodes
        };
        let queue = ChunkQueue::new(order);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for _ in 0..200 {
            const FREE: u64 = u64::MAX;
            let holder: Vec<AtomicU64> = (0..model.num_nodes())
                .map(|_| AtomicU64::new(FREE))
                .collect();
            // 1 + the colour of the last chunk that reached the node
            let reached: Vec<AtomicU64> =
                (0..model.num_nodes()).map(|_| AtomicU64::new(0)).collect();
            let runs: Vec<AtomicU32> = (0..order.waits_for.len())
                .map(|_| AtomicU32::new(0))
                .collect();
            pool.install(|| {
                queue.run_all(order, |p| {
                    runs[p].fetch_add(1, Ordering::Relaxed);
                    let nodes = nodes_of(p);
                    for &n in &nodes {
                        let was = holder[n].swap(p as u64, Ordering::AcqRel);
                        assert_eq!(was, FREE, "chunks {was} and {p} ran at once at node {n}");
                        let before = reached[n].swap(colour_of[p] + 1, Ordering::Relaxed);
                        assert!(
                            before <= colour_of[p],
                            "node {n} reached out of colour order"
                        );
                    }
                    for &n in &nodes {
                        holder[n].store(FREE, Ordering::Release);
                    }
                })
            });
            assert!(runs.iter().all(|r| r.load(Ordering::Relaxed) == 1));
        }
        // a chunk that panics: the panic reaches the caller, and the queue runs again
        let middle = order.waits_for.len() / 2;
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                pool.install(|| queue.run_all(order, |p| assert_ne!(p, middle, "a bad chunk")))
            }));
            assert!(outcome.is_err(), "{threads} threads");
            let count = AtomicUsize::new(0);
            pool.install(|| {
                queue.run_all(order, |_| {
                    count.fetch_add(1, Ordering::Relaxed);
                })
            });
            assert_eq!(count.load(Ordering::Relaxed), order.waits_for.len());
        }
    }
}
