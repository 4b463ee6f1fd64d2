//! Broad phase: which grain pairs, which slave nodes and which facets can touch before the
//! next rebuild (a Verlet-list scheme).
//!
//! At a rebuild, every grain's box (over its current surface nodes) is inflated by
//! r_g = skin + ½ h_max(g); grain pairs whose inflated boxes overlap are found by sweep and
//! prune along x. For each pair and each direction (slave → master) the slave surface nodes
//! inside the master's inflated box query the master's facet [`Bvh`] with a box of half-size
//! skin + ½ h(node); of the facets found, those that can become the node's nearest before
//! the next rebuild (closer than its nearest now + 2 skin, `keep_facets_that_can_become_
//! nearest`) are its candidates until then. A node whose gap to its nearest facet exceeds
//! the skin gets no entry: the gap cannot close before the next rebuild (`within_reach`
//! never selects it). Walls list the surface nodes within 1.5 skin of their plane.
//!
//! Why this is complete: between rebuilds no surface node moves by d_max ≥ skin/2, so a
//! node–facet distance shrinks by less than 2 d_max < skin; a node that now penetrates a
//! facet by up to ½ h (deeper is reported as tunnelling) was within skin + ½ h of it at the
//! rebuild, hence a candidate. For walls, d_max + (wall motion along its normal) < skin/2
//! keeps every node that can reach the plane within the next step in the list.
//!
//! The skin adapts to how fast the surfaces move ([`next_skin`]): it starts at the contact
//! margin (the largest, what the halo and the partition are planned with), doubles (up to
//! the margin) when a rebuild comes sooner than [`GROW_BELOW`] steps after the last, and
//! shrinks when a check every [`SKIN_CHECK_EVERY`] steps finds the surfaces so slow that a
//! skin a quarter as thick or thinner would last [`SKIN_LASTS`] steps. A quasi-static
//! packing moves micrometres over the whole test, a fraction of the margin (½ the
//! smallest surface edge): its lists then hold the facets around each contact point and
//! not a ring of them 25 µm wide (docs/BENCHMARKS.md, session 36). Which candidates the
//! lists hold changes what is evaluated, never the result of an evaluation.
//!
//! The work per step is one pass over the cached entries (which slave nodes can have
//! reached their master since the rebuild: `CandidateLists::within_reach`) and the narrow
//! phase over those within reach, i.e. over the surface nodes near contact, not grain
//! pairs × facets. Of those, a node an evaluation found outside by s is skipped until the
//! nodes can have travelled s/2 since (the travel odometer, from the integrator's largest
//! speed): in a packing that leaves the nodes in contact and the few about to be.
//!
//! Both bounds rest on one property: a gap closes by at most the sum of how far the slave
//! node and the master's nodes moved. The surface motion they need is measured exactly
//! every [`MEASURE_MOTION_EVERY`] steps and bounded by the travel in between.

use super::narrow::{
    closest_point_on_triangle, locate_on_facet, Aabb, Bvh, CandidateFacet, Entry, Pass,
};
use super::triangle::nearest_candidate;
use super::ContactModel;
use crate::math::{dot, sub};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Where the surfaces were when the candidate lists were last rebuilt: part of the run's
/// state, because the rebuild schedule and the narrow phase's "moved since the rebuild"
/// bound depend on it. A restored run rebuilds its lists at these positions and so
/// continues exactly as the uninterrupted run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DetectionReference {
    /// False until the first rebuild.
    pub built: bool,
    /// Surface node positions at the last rebuild (flat surface order, m).
    #[serde(with = "crate::packed_vectors")]
    pub x_ref: Vec<[f64; 3]>,
    /// Wall displacements at the last rebuild (m).
    pub wall_ref: Vec<[f64; 3]>,
    /// Number of rebuilds so far.
    pub rebuilds: u64,
    /// The skin the lists were built with (m); 0 before the first rebuild (and in a
    /// checkpoint written before the skin adapted: the model's margin then).
    #[serde(default)]
    pub skin: f64,
    /// Step of the last rebuild.
    #[serde(default)]
    pub built_at: u64,
}

impl DetectionReference {
    /// True at step `step` when it checks whether a thinner skin would do: every
    /// [`SKIN_CHECK_EVERY`] steps since the rebuild.
    pub fn checks_skin_at(&self, step: u64) -> bool {
        let since = step.saturating_sub(self.built_at);
        self.built && since > 0 && since.is_multiple_of(SKIN_CHECK_EVERY)
    }

    /// The skin the lists were built with (m).
    pub fn skin(&self, cm: &ContactModel) -> f64 {
        if self.skin > 0.0 {
            self.skin
        } else {
            cm.margin
        }
    }
}

/// Steps between the checks whether a thinner skin would do (see [`next_skin`]); every
/// rank measures the surface motion exactly at these steps, so the check reads the same
/// largest displacement on any number of ranks.
pub const SKIN_CHECK_EVERY: u64 = 1024;
/// A skin is made thinner when one at most a quarter as thick lasts this many steps at the
/// pace since the last rebuild.
pub const SKIN_LASTS: u64 = 8192;
/// A rebuild sooner than this many steps after the last one doubles the skin.
pub const GROW_BELOW: u64 = 256;
/// The thinnest skin, as a fraction of the contact margin.
pub const SKIN_FLOOR: f64 = 1.0 / 64.0;

/// The skin to rebuild the lists with at step `step`, or `None` to keep them: without
/// lists (the first build, or after a migration dropped them), the reference's skin (the
/// margin when it has none); after a rebuild `voted` by some rank (a list may miss a
/// contact), the same skin, doubled (up to the margin) when it lasted less than
/// [`GROW_BELOW`] steps; at a check step (every
/// [`SKIN_CHECK_EVERY`] steps since the rebuild), a thinner one when the surfaces moved so
/// little that 2 × (their pace) × [`SKIN_LASTS`] is at most a quarter of it. `moved` is
/// the largest displacement of any surface node since the rebuild (every rank's, measured
/// exactly at a check step) and `wall_moved` the largest wall motion along its normal.
/// Every argument is the same on every rank, so all choose alike.
pub fn next_skin(
    cm: &ContactModel,
    reference: &DetectionReference,
    step: u64,
    moved: f64,
    wall_moved: f64,
    voted: bool,
) -> Option<f64> {
    let skin = reference.skin(cm);
    if !reference.built {
        // the first build, or lists dropped with a migration (which keeps the skin)
        return Some(skin);
    }
    let since = step.saturating_sub(reference.built_at);
    if voted {
        return Some(if since < GROW_BELOW {
            (2.0 * skin).min(cm.margin)
        } else {
            skin
        });
    }
    if !reference.checks_skin_at(step) {
        return None;
    }
    let pace = (moved + wall_moved) / since as f64;
    let wanted = (2.0 * pace * SKIN_LASTS as f64).max(SKIN_FLOOR * cm.margin);
    (wanted <= 0.25 * skin).then_some(wanted)
}

/// Cached broad-phase data (scratch: derived from the [`DetectionReference`], never
/// serialised).
#[derive(Debug, Default, Clone)]
pub struct BroadPhase {
    /// True once the lists match the current reference.
    pub built: bool,
    /// Current surface box of every grain (at the last rebuild).
    pub boxes: Vec<Aabb>,
    /// Candidate grain pairs (model grain indices, a < b).
    pub pairs: Vec<(u32, u32)>,
    /// Largest surface-node displacement since the last rebuild, as of the last check (m):
    /// this rank's nodes after [`BroadPhase::needs_rebuild`], every rank's once the step has
    /// taken the maximum over ranks (before the narrow phase uses it).
    pub moved: f64,
    /// How each surface (aligned with `ContactModel::surfaces`) has moved since the last
    /// rebuild: this rank's surfaces after [`BroadPhase::needs_rebuild`], a plain ghost's
    /// once the step has taken its owner's ([`SurfaceMotion::UNKNOWN`] until then).
    pub motion: Vec<SurfaceMotion>,
    /// The last exact measure of `moved` and `motion`, and how far the nodes can have
    /// travelled since: what bounds them in the steps between measures.
    measured: MeasuredMotion,
    /// The last [`BroadPhase::note_travel`]: (step, travel into it).
    travel_into: Option<(u64, f64)>,
    /// Keep the skin at the contact margin (a reference for tests of the adaptive one).
    pub fixed_skin: bool,
    /// Largest wall motion along its normal since the last rebuild, as of the last
    /// [`BroadPhase::needs_rebuild`] (m; the walls are the same on every rank).
    pub wall_moved: f64,
    order: Vec<u32>,
    bvh_built: Vec<bool>,
}

/// Steps between exact measures of the surface motion by default (see
/// [`BroadPhase::note_travel`]).
pub const MEASURE_MOTION_EVERY: u64 = 16;

/// An exact measure of the surface motion and the travel bound accumulated since.
///
/// Why: the exact measure reads every surface node this rank moves (x and its reference),
/// a pass over scattered memory that cost a tenth of the contact stage on the 2000-sphere
/// block; between measures, `moved + travel` and each spread + 3 `travel` are upper bounds
/// that cost nothing (docs/BENCHMARKS.md, session 34).
#[derive(Debug, Clone)]
struct MeasuredMotion {
    /// Steps between exact measures; 1 measures every step.
    every: u64,
    /// Step of the last exact measure; `None` when the bound is broken (no measure yet,
    /// a rebuild, a step whose travel was not noted).
    at: Option<u64>,
    /// The step whose positions the bound covers.
    reaches: u64,
    /// Σ over the steps since the measure of the farthest any node this rank moves went
    /// in that step (m).
    travel: f64,
    /// Exact measures so far.
    count: u64,
    /// `moved` and `motion` at the measure.
    moved: f64,
    motion: Vec<SurfaceMotion>,
    /// Largest coordinate magnitude of the surfaces at the rebuild (m): sets the rounding
    /// slack of the bound (a measure rounds each displacement to a few ulps of it).
    extent: f64,
}

impl Default for MeasuredMotion {
    fn default() -> Self {
        Self {
            every: MEASURE_MOTION_EVERY,
            at: None,
            count: 0,
            reaches: 0,
            travel: 0.0,
            moved: 0.0,
            motion: Vec::new(),
            extent: 0.0,
        }
    }
}

/// A surface's motion since the last rebuild: the displacement of its first node, and the
/// farthest any of its nodes has moved from that displacement (rotation and deformation).
/// Two surfaces then have closed a gap between them by at most
/// |shift_a − shift_b| + spread_a + spread_b: a grain pair that moved together (the
/// neighbours in a packing under homogeneous strain) closed little of it, however far
/// both travelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceMotion {
    /// m.
    pub shift: [f64; 3],
    /// m; infinite when unknown.
    pub spread: f64,
}

impl MeasuredMotion {
    /// Keeps the exact measure of step `step`.
    fn record(&mut self, step: u64, moved: f64, motion: &[SurfaceMotion]) {
        self.count += 1;
        self.at = Some(step);
        self.reaches = step;
        self.travel = 0.0;
        self.moved = moved;
        self.motion.clear();
        self.motion.extend_from_slice(motion);
    }
}

impl SurfaceMotion {
    /// Not known on this rank: bounds nothing.
    pub const UNKNOWN: Self = Self {
        shift: [0.0; 3],
        spread: f64::INFINITY,
    };
    /// At the reference positions.
    pub const AT_REST: Self = Self {
        shift: [0.0; 3],
        spread: 0.0,
    };

    /// Bound of how much of a gap between the two surfaces has closed (m).
    #[inline]
    pub fn closing_with(&self, other: &Self) -> f64 {
        let d = sub(self.shift, other.shift);
        dot(d, d).sqrt() + self.spread + other.spread
    }
}

/// Outputs of a rebuild that the narrow phase and walls consume.
#[derive(Debug, Default, Clone)]
pub struct CandidateLists {
    pub passes: Vec<Pass>,
    pub entries: Vec<Entry>,
    /// Per entry: the slave node's distance to the master surface at the rebuild (m), 0 if
    /// it was inside. While no node has moved by more than half of it since, the node
    /// cannot penetrate and is skipped. Kept apart from the entries because every step
    /// scans all of them and reads the few entries within reach only.
    pub gap_at_rebuild: Vec<f64>,
    /// The entries of each pass (entries are built pass by pass).
    pub pass_entries: Vec<std::ops::Range<u32>>,
    /// The entries' candidate facets, as records the narrow phase reads instead of the
    /// model's topology arrays (see `super::candidate_facet`).
    pub candidate_facets: Vec<CandidateFacet>,
    /// (wall index, flat surface node index), ordered by wall then node.
    pub wall_nodes: Vec<(u32, u32)>,
    pub bvh: Vec<Bvh>,
    query: Vec<u32>,
    /// Σ over the steps since the lists were built of how far any node of any rank can
    /// have gone in the step (m); `None` while a step's travel is unknown (a periodic
    /// cell), when no entry is skipped by it.
    odometer: Option<f64>,
    /// Per entry: the `odometer` reading before which its node cannot have reached the
    /// master: when an evaluation finds the node outside by s, the reading then + s/2 (the
    /// gap closes by at most the travel of each side, as for `gap_at_rebuild`); −∞ when
    /// it is to be evaluated.
    resume_at: Vec<f64>,
}

impl CandidateLists {
    /// Indices of the entries whose slave node can have reached its master surface since
    /// the rebuild, ascending, into `out`: those whose gap then is at most what the pass's
    /// two surfaces can have closed of it. That is at most 2 `moved` (no node has moved
    /// more than `moved`; each side closes the gap by at most that), and at most
    /// [`SurfaceMotion::closing_with`] of the two surfaces' `motion`.
    ///
    /// Of those, an entry whose node an earlier evaluation found too far outside to have
    /// arrived since (see `resume_at`) is skipped: in a packing most entries within reach
    /// are the rings around the contact points, micrometres away, which the travel of a
    /// few thousand steps cannot close.
    pub fn within_reach(&self, moved: f64, motion: &[SurfaceMotion], out: &mut Vec<u32>) {
        out.clear();
        let odometer = self.odometer;
        for (p, range) in self.passes.iter().zip(&self.pass_entries) {
            let (s, m) = (p.slave as usize, p.master as usize);
            let closing = match (motion.get(s), motion.get(m)) {
                (Some(a), Some(b)) => a.closing_with(b).min(2.0 * moved),
                _ => 2.0 * moved,
            };
            let (start, end) = (range.start as usize, range.end as usize);
            // branch-free: every index is written, the count advances where it qualifies
            // (which entries do is unpredictable, a branch per entry mispredicted often)
            let mut kept = out.len();
            out.resize(kept + (end - start), 0);
            let gaps = &self.gap_at_rebuild[start..end];
            match odometer {
                Some(o) => {
                    let resume = &self.resume_at[start..end];
                    for (i, (&d0, &r)) in gaps.iter().zip(resume).enumerate() {
                        out[kept] = (start + i) as u32;
                        kept += usize::from((d0 <= closing) & (r <= o));
                    }
                }
                None => {
                    for (i, &d0) in gaps.iter().enumerate() {
                        out[kept] = (start + i) as u32;
                        kept += usize::from(d0 <= closing);
                    }
                }
            }
            out.truncate(kept);
        }
    }

    /// Advances the odometer by `travel`, the farthest any node of any rank went in the
    /// step that led to the positions about to be evaluated (not finite: unknown).
    pub fn advance_odometer(&mut self, travel: f64) {
        if travel.is_finite() {
            self.odometer = Some(self.odometer.unwrap_or(0.0) + travel);
        } else if self.odometer.take().is_some() {
            self.resume_at.fill(f64::NEG_INFINITY);
        }
    }

    /// Records, for the entries `evaluated` with the outcomes `outside` (the separation of
    /// a node found outside, m; `None` for one in contact), when each must be evaluated
    /// again.
    pub fn note_separations(
        &mut self,
        evaluated: &[u32],
        outside: impl Iterator<Item = Option<f64>>,
    ) {
        let Some(odometer) = self.odometer else {
            return;
        };
        for (&i, separation) in evaluated.iter().zip(outside) {
            // a hair short of s/2, for the rounding of the readings
            self.resume_at[i as usize] =
                separation.map_or(f64::NEG_INFINITY, |s| odometer + 0.5 * s * (1.0 - 1e-9));
        }
    }
}

impl BroadPhase {
    /// Largest displacement of a surface node since the last rebuild (m), over the nodes
    /// this rank moves or shifts: owned grains and periodic images; and the [`motion`] of
    /// those surfaces (the others' is unknown). A plain ghost's nodes are its owner's to
    /// count (the rebuild decision is a max over ranks, its motion the owner's), and with
    /// a trimmed halo most of them are dormant copies. Deterministic (max is exact) and
    /// parallel over surfaces.
    ///
    /// [`motion`]: BroadPhase::motion
    pub fn max_displacement(
        &mut self,
        cm: &ContactModel,
        x: &[[f64; 3]],
        reference: &DetectionReference,
    ) -> f64 {
        let x_ref = &reference.x_ref;
        self.motion
            .resize(cm.surfaces.len(), SurfaceMotion::UNKNOWN);
        let largest = |m: &mut SurfaceMotion, g: &super::GrainSurface| -> f64 {
            if !g.moves_here() {
                *m = SurfaceMotion::UNKNOWN;
                return 0.0;
            }
            let displacement = |k: usize| sub(x[cm.node[k] as usize], x_ref[k]);
            let shift = g.nodes.clone().next().map_or([0.0; 3], displacement);
            let (mut largest, mut spread): (f64, f64) = (0.0, 0.0);
            for k in g.nodes.clone() {
                let d = displacement(k);
                largest = largest.max(dot(d, d));
                let r = sub(d, shift);
                spread = spread.max(dot(r, r));
            }
            *m = SurfaceMotion {
                shift,
                spread: spread.sqrt(),
            };
            largest
        };
        (self.motion.par_iter_mut())
            .zip(cm.surfaces.par_iter())
            .map(|(m, g)| largest(m, g))
            .reduce(|| 0.0, f64::max)
            .sqrt()
    }

    /// True when lists built at `reference` may miss a contact at positions `x` (those of
    /// step `step`) and wall displacements `wall_next` (those at t_{n+1}). Sets `moved`
    /// and `motion`: measured, or between measures bounded by the travel since the last
    /// one; a rebuild is decided on measured values only, so the rebuild steps do not
    /// depend on the measuring schedule.
    pub fn needs_rebuild(
        &mut self,
        cm: &ContactModel,
        x: &[[f64; 3]],
        wall_next: &[[f64; 3]],
        reference: &DetectionReference,
        step: u64,
    ) -> bool {
        if !reference.built {
            return true;
        }
        let skin = reference.skin(cm);
        self.wall_moved = (cm.walls.iter().enumerate())
            .map(|(w, wall)| dot(sub(wall_next[w], reference.wall_ref[w]), wall.normal).abs())
            .fold(0.0, f64::max);
        let wall_moved = self.wall_moved;
        let due =
            |d: f64| 2.0 * d >= skin || (!cm.walls.is_empty() && d + wall_moved >= 0.5 * skin);
        let skin_check = reference.checks_skin_at(step);
        if let Some(bound) = self.bounded_motion(cm, step).filter(|_| !skin_check) {
            if !due(bound) {
                self.moved = bound;
                return false;
            }
        }
        let d = self.max_displacement(cm, x, reference);
        self.moved = d;
        self.measured.record(step, d, &self.motion);
        due(d)
    }

    /// Records that no node this rank moves went farther than `travel` (m) in the step
    /// that reached step `step` (the integrator's Δt max|v_{n+½}|). Without the note for
    /// every step since the last exact measure, the next check measures again: a caller
    /// that also moves nodes otherwise (a periodic cell shifts its images) does not note.
    pub fn note_travel(&mut self, step: u64, travel: f64) {
        self.travel_into = Some((step, travel));
        let m = &mut self.measured;
        if m.at.is_some() && m.reaches + 1 == step && travel.is_finite() {
            m.reaches = step;
            m.travel += travel;
        } else {
            m.at = None;
        }
    }

    /// This rank's travel into step `step` (m), as noted by [`BroadPhase::note_travel`];
    /// infinite when not noted.
    pub fn travel_into(&self, step: u64) -> f64 {
        match self.travel_into {
            Some((noted, travel)) if noted == step && self.measured.every > 1 => travel,
            _ => f64::INFINITY,
        }
    }

    /// Measures the surface motion every `steps` steps and bounds it by the travel in
    /// between. 1 takes no bound from the travel at all: every step measures, and no
    /// entry is skipped by its separation (see [`CandidateLists::within_reach`]).
    pub fn bound_by_travel(&mut self, steps: u64) {
        self.measured.every = steps.max(1);
        self.measured.at = None;
    }

    /// Exact measures of the surface motion taken so far.
    pub fn motion_measures(&self) -> u64 {
        self.measured.count
    }

    /// `moved` bounded by the last measure plus the travel since, with `motion` set to the
    /// matching bounds, when the bound covers step `step` and the measure is recent.
    fn bounded_motion(&mut self, cm: &ContactModel, step: u64) -> Option<f64> {
        let m = &self.measured;
        let at = m.at?;
        if m.reaches != step || step - at >= m.every || m.motion.len() != cm.surfaces.len() {
            return None;
        }
        // the first node is off its measured shift by ≤ travel, every node off its measured
        // offset from the first by ≤ 2 travel: closing_with grows by ≤ 6 travel per pair
        // (with the rounding of the measures on top)
        let travel = m.travel + 16.0 * f64::EPSILON * m.extent;
        let grown = |(g, m): (&super::GrainSurface, &SurfaceMotion)| {
            if g.moves_here() {
                SurfaceMotion {
                    shift: m.shift,
                    spread: m.spread + 3.0 * travel,
                }
            } else {
                SurfaceMotion::UNKNOWN
            }
        };
        self.motion.clear();
        self.motion
            .extend(cm.surfaces.iter().zip(&self.measured.motion).map(grown));
        Some(self.measured.moved + travel)
    }

    /// Rebuilds the lists at positions `x` (walls at displacements `wall_now`) and makes
    /// them the new `reference`.
    #[allow(clippy::too_many_arguments)]
    pub fn rebuild(
        &mut self,
        cm: &ContactModel,
        x: &[[f64; 3]],
        wall_now: &[[f64; 3]],
        lists: &mut CandidateLists,
        reference: &mut DetectionReference,
        skin: f64,
        step: u64,
    ) {
        reference.rebuilds += 1;
        reference.built = true;
        reference.skin = skin;
        reference.built_at = step;
        reference.x_ref.clear();
        reference
            .x_ref
            .extend(cm.node.iter().map(|&n| x[n as usize]));
        reference.wall_ref.clear();
        reference.wall_ref.extend_from_slice(wall_now);
        self.moved = 0.0;
        self.motion.clear();
        self.motion
            .resize(cm.surfaces.len(), SurfaceMotion::AT_REST);
        self.measured.at = None;
        self.build_lists(cm, x, wall_now, lists, skin);
    }

    /// Rebuilds the lists of an existing `reference` (after a restore or a migration of
    /// state): the surface nodes are put back where they were at that rebuild, so the
    /// lists equal the ones the uninterrupted run built there.
    pub fn restore(
        &mut self,
        cm: &ContactModel,
        x: &[[f64; 3]],
        reference: &DetectionReference,
        lists: &mut CandidateLists,
    ) {
        let mut x_then = x.to_vec();
        for (k, &n) in cm.node.iter().enumerate() {
            x_then[n as usize] = reference.x_ref[k];
        }
        self.build_lists(cm, &x_then, &reference.wall_ref, lists, reference.skin(cm));
    }

    /// Pairs, slave entries, candidate facets and wall node lists at positions `x`, for
    /// surfaces that move less than `skin`/2 until the next rebuild.
    fn build_lists(
        &mut self,
        cm: &ContactModel,
        x: &[[f64; 3]],
        wall_now: &[[f64; 3]],
        lists: &mut CandidateLists,
        skin: f64,
    ) {
        self.built = true;
        let ng = cm.surfaces.len();
        self.boxes.clear();
        for g in &cm.surfaces {
            let mut b = Aabb::EMPTY;
            for k in g.nodes.clone() {
                b.grow(x[cm.node[k] as usize]);
            }
            self.boxes.push(b);
        }
        self.measured.extent = (self.boxes.iter())
            .flat_map(|b| b.min.into_iter().chain(b.max))
            .filter(|c| c.is_finite())
            .fold(0.0, |e, c| e.max(c.abs()));
        let reach = |g: usize| skin + 0.5 * cm.surfaces[g].h_max;

        // Sweep and prune along x over the inflated boxes.
        self.pairs.clear();
        if cm.grain_contact {
            self.order.clear();
            self.order.extend(0..ng as u32);
            let lo = |g: u32| self.boxes[g as usize].min[0] - reach(g as usize);
            let order = &mut self.order;
            order.sort_unstable_by(|&a, &b| lo(a).total_cmp(&lo(b)).then(a.cmp(&b)));
            for i in 0..order.len() {
                let a = order[i] as usize;
                let ba = self.boxes[a].inflated(reach(a));
                for &bj in &order[i + 1..] {
                    let b = bj as usize;
                    let bb = self.boxes[b].inflated(reach(b));
                    if bb.min[0] > ba.max[0] {
                        break;
                    }
                    // a pair of two ghosts is another rank's business
                    if ba.overlaps(&bb) && (cm.surfaces[a].owned || cm.surfaces[b].owned) {
                        self.pairs.push((a.min(b) as u32, a.max(b) as u32));
                    }
                }
            }
            self.pairs.sort_unstable();
        }

        // Per-grain BVHs for grains in a pair, then the two passes of every pair.
        lists.bvh.resize_with(ng, Bvh::default);
        self.bvh_built.clear();
        self.bvh_built.resize(ng, false);
        lists.passes.clear();
        for &(a, b) in &self.pairs {
            lists.passes.push(Pass {
                slave: a,
                master: b,
            });
            lists.passes.push(Pass {
                slave: b,
                master: a,
            });
            for g in [a as usize, b as usize] {
                if !self.bvh_built[g] {
                    lists.bvh[g].build(cm, cm.surfaces[g].facets.clone(), x);
                    self.bvh_built[g] = true;
                }
            }
        }
        // Global ids, not model indices: a rank holds owned grains first and ghosts after,
        // and the force accumulation order must not depend on that layout.
        lists.passes.sort_unstable_by_key(|p| {
            let (s, m) = (
                &cm.surfaces[p.slave as usize],
                &cm.surfaces[p.master as usize],
            );
            (s.global_id, m.global_id, s.image, m.image)
        });
        lists.entries.clear();
        lists.pass_entries.clear();
        lists.gap_at_rebuild.clear();
        lists.odometer = Some(0.0);
        lists.candidate_facets.clear();
        for (pi, pass) in lists.passes.iter().enumerate() {
            let first_entry = lists.entries.len() as u32;
            let (s, m) = (pass.slave as usize, pass.master as usize);
            let zone = self.boxes[m].inflated(reach(s));
            for k in cm.surfaces[s].nodes.clone() {
                let p = x[cm.node[k] as usize];
                if !zone.contains(p) {
                    continue;
                }
                let q = Aabb::around(p, skin + 0.5 * cm.node_h[k]);
                lists.query.clear();
                lists.bvh[m].query(&q, &mut lists.query);
                let Some(nearest) = nearest_candidate(cm, x, p, &lists.query) else {
                    continue;
                };
                let facet = lists.query[nearest] as usize;
                let d0 = (-locate_on_facet(cm, x, p, facet).depth).max(0.0);
                // until the next rebuild a gap closes by less than the skin
                // (`within_reach`): a node farther out cannot reach its master before then
                if d0 > skin {
                    continue;
                }
                keep_facets_that_can_become_nearest(cm, x, p, facet, skin, &mut lists.query);
                let start = lists.candidate_facets.len() as u32;
                let records = lists
                    .query
                    .iter()
                    .map(|&f| CandidateFacet::of(cm, f as usize));
                lists.candidate_facets.extend(records);
                lists.entries.push(Entry {
                    slave: k as u32,
                    pass: pi as u32,
                    start,
                    end: lists.candidate_facets.len() as u32,
                });
                lists.gap_at_rebuild.push(d0);
            }
            lists
                .pass_entries
                .push(first_entry..lists.entries.len() as u32);
        }
        lists.resume_at.clear();
        lists
            .resume_at
            .resize(lists.entries.len(), f64::NEG_INFINITY);

        // Walls: surface nodes within 1.5 skin of the plane.
        lists.wall_nodes.clear();
        for (w, wall) in cm.walls.iter().enumerate() {
            let p = wall.point_at_displacement(wall_now[w]);
            let n = wall.normal;
            for (g, surf) in cm.surfaces.iter().enumerate() {
                if !surf.owned {
                    continue; // a ghost's wall contact is computed by its owner
                }
                let b = &self.boxes[g];
                // signed distance of the box's lowest corner along n
                let mut lowest = 0.0;
                for i in 0..3 {
                    let c = if n[i] >= 0.0 { b.min[i] } else { b.max[i] };
                    lowest += (c - p[i]) * n[i];
                }
                if lowest > 1.5 * skin {
                    continue;
                }
                for k in surf.nodes.clone() {
                    if dot(sub(x[cm.node[k] as usize], p), n) <= 1.5 * skin {
                        lists.wall_nodes.push((w as u32, k as u32));
                    }
                }
            }
        }
    }
}

/// Keeps, of the facets `query` found around the slave node at `p`, those that can be its
/// nearest facet before the next rebuild; `nearest` is its nearest now (flat distance D₀).
///
/// The flat distance from a point to a surface moves by no more than the point and the
/// surface do, and until the next rebuild a slave node and a master facet move by less
/// than `skin` together (the module docs). A facet nearest at a later step, at distance
/// D ≤ D₀ + skin then, was therefore closer than D₀ + 2 skin now; every other facet is
/// dropped. The order of the rest is kept, so the first of equally near facets is the
/// same. In a packing D₀ is the contact's sub-micrometre depth and the skin a few
/// micrometres: the list shrinks from the ring of facets a half-edge box meets to those at
/// the contact point (six where the node faces a master vertex; docs/BENCHMARKS.md,
/// session 37).
fn keep_facets_that_can_become_nearest(
    cm: &ContactModel,
    x: &[[f64; 3]],
    p: [f64; 3],
    nearest: usize,
    skin: f64,
    query: &mut Vec<u32>,
) {
    // the relative slack covers the rounding of the distances, many orders above it
    let reach = (facet_distance(cm, x, p, nearest) + 2.0 * skin) * (1.0 + 1e-6);
    query.retain(|&f| facet_distance(cm, x, p, f as usize) <= reach);
}

/// Flat distance from `p` to facet `f` at positions `x` (what the narrow phase ranks
/// candidates by).
fn facet_distance(cm: &ContactModel, x: &[[f64; 3]], p: [f64; 3], f: usize) -> f64 {
    let [a, b, c] = cm.facet[f].map(|n| x[n as usize]);
    closest_point_on_triangle(p, a, b, c).dist2.sqrt()
}

#[cfg(test)]
mod tests;
