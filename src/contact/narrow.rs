//! Narrow phase: surface nodes against surface facets.
//!
//! - [`closest_point_on_triangle`] (in [`super::triangle`]): exact closest point with the
//!   feature it lies on (face, edge or vertex) and its barycentric coordinates; the
//!   nearest of a node's candidate facets is found in f64 lanes there.
//! - [`Bvh`]: a bounding-volume hierarchy over the facet boxes of one grain, built at each
//!   broad-phase rebuild and queried with the boxes of nearby surface nodes of other grains.
//! - [`evaluate_entry`]: one slave node against its candidate facets of one master grain:
//!   penetration, normal, penalty pressure, friction, energies.
//!
//! Inside/outside is decided with pseudo-normals (Bærentzen & Aanæs 2005): the facet normal
//! when the closest point is inside a facet, the sum of the two facet normals on an edge, the
//! angle-weighted vertex normal on a vertex. The penetration depth is the distance to the
//! closest surface point, which is continuous as a node crosses facet edges, so the penalty
//! force has no jump there.
//!
//! The master surface is curved ([`super::patch`]): each facet's Phong patch, so the
//! contact normal and the penetration follow the body's shape rather than the facets'
//! (a faceted normal tilts with the tangential offset of a node-on-node contact and takes
//! the tilt off the friction angle).

pub use super::candidate_facet::CandidateFacet;
use super::friction::{return_map, rotate_onto_plane, tangential};
use super::patch::Patch;
pub use super::triangle::{closest_point_on_triangle, Closest, Feature};
use super::triangle::{nearest_candidate, nearest_record};
use super::vertex_normals::{
    corners_normal, pseudo_normal_at_vertex, smooth_normal, triangle_normal,
};
use super::{ContactKey, ContactModel, FrictionPoint};
use crate::math::{add, dot, norm, scale, sub};

/// Axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: [f64::INFINITY; 3],
        max: [f64::NEG_INFINITY; 3],
    };

    #[inline]
    pub fn grow(&mut self, p: [f64; 3]) {
        for (i, &c) in p.iter().enumerate() {
            self.min[i] = self.min[i].min(c);
            self.max[i] = self.max[i].max(c);
        }
    }

    #[inline]
    pub fn union(&mut self, o: &Aabb) {
        for i in 0..3 {
            self.min[i] = self.min[i].min(o.min[i]);
            self.max[i] = self.max[i].max(o.max[i]);
        }
    }

    #[inline]
    pub fn inflated(&self, r: f64) -> Aabb {
        Aabb {
            min: self.min.map(|v| v - r),
            max: self.max.map(|v| v + r),
        }
    }

    #[inline]
    pub fn around(p: [f64; 3], r: f64) -> Aabb {
        Aabb {
            min: p.map(|v| v - r),
            max: p.map(|v| v + r),
        }
    }

    #[inline]
    pub fn overlaps(&self, o: &Aabb) -> bool {
        (0..3).all(|i| self.min[i] <= o.max[i] && o.min[i] <= self.max[i])
    }

    #[inline]
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|i| self.min[i] <= p[i] && p[i] <= self.max[i])
    }

    #[inline]
    fn centre(&self) -> [f64; 3] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
            0.5 * (self.min[2] + self.max[2]),
        ]
    }
}

#[derive(Debug, Clone, Copy)]
struct Prim {
    facet: u32,
    bbox: Aabb,
    centre: [f64; 3],
}

#[derive(Debug, Clone, Copy)]
struct BvhNode {
    bbox: Aabb,
    /// Leaf: first primitive; internal: index of the right child (left child = self + 1).
    start: u32,
    /// Number of primitives in a leaf, 0 for an internal node.
    count: u32,
}

/// Bounding-volume hierarchy over the facets of one grain (median split on the longest
/// axis, leaves of ≤ 4 facets). Buffers are reused across rebuilds.
#[derive(Debug, Default, Clone)]
pub struct Bvh {
    prims: Vec<Prim>,
    nodes: Vec<BvhNode>,
}

const LEAF_SIZE: usize = 4;

impl Bvh {
    /// Rebuilds over the facets `facets` (global facet indices) at positions `x`.
    pub fn build(&mut self, cm: &ContactModel, facets: std::ops::Range<usize>, x: &[[f64; 3]]) {
        self.prims.clear();
        for f in facets {
            let mut bbox = Aabb::EMPTY;
            for &n in &cm.facet[f] {
                bbox.grow(x[n as usize]);
            }
            self.prims.push(Prim {
                facet: f as u32,
                bbox,
                centre: bbox.centre(),
            });
        }
        self.nodes.clear();
        if !self.prims.is_empty() {
            self.build_range(0, self.prims.len());
        }
    }

    /// Builds the subtree over `prims[s..e]` and returns its node index (depth-first
    /// layout: the left child follows its parent, `start` holds the right child).
    fn build_range(&mut self, s: usize, e: usize) -> u32 {
        let ni = self.nodes.len();
        let mut bbox = Aabb::EMPTY;
        let mut cbox = Aabb::EMPTY;
        for p in &self.prims[s..e] {
            bbox.union(&p.bbox);
            cbox.grow(p.centre);
        }
        self.nodes.push(BvhNode {
            bbox,
            start: s as u32,
            count: (e - s) as u32,
        });
        if e - s <= LEAF_SIZE {
            return ni as u32;
        }
        let ext = [0, 1, 2].map(|i| cbox.max[i] - cbox.min[i]);
        let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
            0
        } else if ext[1] >= ext[2] {
            1
        } else {
            2
        };
        let mid = (s + e) / 2;
        self.prims[s..e].select_nth_unstable_by(mid - s, |a, b| {
            a.centre[axis]
                .total_cmp(&b.centre[axis])
                .then(a.facet.cmp(&b.facet))
        });
        self.build_range(s, mid);
        let right = self.build_range(mid, e);
        self.nodes[ni].start = right;
        self.nodes[ni].count = 0;
        ni as u32
    }

    /// Appends to `out` the facets whose box overlaps `q`, in ascending facet order.
    pub fn query(&self, q: &Aabb, out: &mut Vec<u32>) {
        let first = out.len();
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !node.bbox.overlaps(q) {
                continue;
            }
            if node.count > 0 {
                let s = node.start as usize;
                for p in &self.prims[s..s + node.count as usize] {
                    if p.bbox.overlaps(q) {
                        out.push(p.facet);
                    }
                }
            } else {
                let me = stack[top] + 1;
                stack[top] = node.start;
                stack[top + 1] = me;
                top += 2;
            }
        }
        out[first..].sort_unstable();
    }
}

/// One (slave grain → master grain) pass of the symmetric two-pass scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pass {
    /// Model grain indices.
    pub slave: u32,
    pub master: u32,
}

/// A slave surface node with its candidate facets of one master grain (cached between
/// broad-phase rebuilds).
#[derive(Debug, Clone, Copy)]
pub struct Entry {
    /// Flat surface-node index (see [`ContactModel::node`]).
    pub slave: u32,
    /// Index into the pass list.
    pub pass: u32,
    /// Range into the candidate facet list.
    pub start: u32,
    pub end: u32,
}

/// Result of one entry at one step.
#[derive(Debug, Clone, Copy, Default)]
pub struct PointResult {
    /// The slave node penetrates the master surface.
    pub active: bool,
    /// Penetration deeper than half the local edge: detection can no longer be trusted.
    pub tunnel: bool,
    /// Index into the pass list (the entry's), so that the passes over the results need
    /// not reach back into the entries.
    pub pass: u32,
    /// Model node ids of the slave node and of the master facet corners.
    pub slave: u32,
    pub masters: [u32; 3],
    /// Barycentric weights of the contact point on the master facet.
    pub weights: [f64; 3],
    /// Force on the slave node (N); master corner k gets −`weights[k]`·force.
    pub force: [f64; 3],
    /// Penetration depth g ≥ 0 (m).
    pub gap: f64,
    /// Outward normal of the master at the contact point.
    pub normal: [f64; 3],
    /// Normal pressure ε_n g (Pa).
    pub pressure: f64,
    /// Penalty ε_n of this point (Pa/m).
    pub penalty: f64,
    /// Area the pressure acts on: slave tributary area × pass weight (m²); the point's
    /// normal spring stiffness is `penalty × area`.
    pub area: f64,
    /// Normal contact damping force on the slave along `normal` (N), included in `force`.
    pub damping_force: f64,
    /// Stored penalty energy (normal + tangential spring) of this point (J).
    pub energy: f64,
    /// Energy dissipated by slip in this step (J).
    pub dissipation: f64,
    /// Tangential traction to remember (Pa).
    pub traction: [f64; 3],
    /// On the Coulomb cone at this step (slipping).
    pub sliding: bool,
    /// When not active: how far outside the master the node is at least (m); infinite
    /// without candidates.
    pub separation: f64,
}

/// Weight of each of the two passes.
pub const PASS_WEIGHT: f64 = 0.5;

/// Inputs shared by all entries of one evaluation.
pub struct EvalContext<'a> {
    pub cm: &'a ContactModel,
    pub passes: &'a [Pass],
    /// The entries' candidate facets (`CandidateLists::candidate_facets`).
    pub facets: &'a [CandidateFacet],
    pub x: &'a [[f64; 3]],
    pub v: &'a [[f64; 3]],
    /// Nodal masses used by the integrator (for the contact damping).
    pub mass: &'a [f64],
    pub dt: f64,
    /// Friction history of the previous step, sorted by key.
    pub history: &'a [FrictionPoint],
    /// Include friction (μ > 0 and not a pure geometric check).
    pub friction: bool,
}

/// Looks up friction points in a history sorted by key, for keys asked in ascending order
/// (entry order is key order: the history is pushed in it): each search gallops forward
/// from where the last one ended, a few comparisons on lines just read, where a binary
/// search over the whole history missed the cache in its last levels (docs/BENCHMARKS.md,
/// session 36). Finds what a binary search finds, for keys in any order.
#[derive(Debug, Clone, Copy, Default)]
pub struct HistoryCursor {
    /// Where the last search ended: every point before it has a smaller key than the last
    /// key asked.
    next: usize,
}

impl HistoryCursor {
    /// The point of `history` with key `key`, if any.
    #[inline(always)]
    pub fn find<'h>(
        &mut self,
        history: &'h [FrictionPoint],
        key: ContactKey,
    ) -> Option<&'h FrictionPoint> {
        let ahead = self.next.min(history.len());
        let start = match ahead.checked_sub(1) {
            Some(last) if history[last].key >= key => 0,
            _ => ahead,
        };
        let rest = &history[start..];
        // gallop: rest[..lo] < key, and rest[hi] ≥ key once the loop ends inside rest
        let (mut lo, mut hi, mut stride) = (0, 0, 1);
        while hi < rest.len() && rest[hi].key < key {
            lo = hi + 1;
            hi += stride;
            stride *= 2;
        }
        let hi = hi.min(rest.len());
        let at = start + lo + rest[lo..hi].partition_point(|p| p.key < key);
        self.next = at;
        history.get(at).filter(|p| p.key == key)
    }
}

/// Outward pseudo-normal of the master surface at a closest-point feature of `facet`.
fn pseudo_normal(
    cm: &ContactModel,
    x: &[[f64; 3]],
    facet: &CandidateFacet,
    feature: Feature,
) -> [f64; 3] {
    match feature {
        Feature::Face => corners_normal(x, facet.corners),
        Feature::Edge(k) => {
            let n = corners_normal(x, facet.corners);
            match facet.across(k as usize) {
                None => n,
                Some(_) => add(n, corners_normal(x, facet.neighbours[k as usize])),
            }
        }
        Feature::Vertex(k) => pseudo_normal_at_vertex(cm, x, facet.corners[k as usize]),
    }
}

/// Where a node is with respect to a master surface.
#[derive(Debug, Clone, Copy)]
pub struct Located {
    pub closest: Closest,
    /// Global facet index of the closest point, and its corners (model node ids).
    pub facet: usize,
    pub corners: [u32; 3],
    /// Penetration depth (> 0 inside the master) or −distance (outside), m.
    pub depth: f64,
    /// Outward master normal at the contact point (unit; meaningful when inside).
    pub normal: [f64; 3],
}

/// Closest point of the candidate facets to `xs` and whether `xs` is inside the master
/// (pseudo-normal test). `None` without candidates.
pub fn locate(
    cm: &ContactModel,
    x: &[[f64; 3]],
    xs: [f64; 3],
    candidates: &[u32],
) -> Option<Located> {
    let facet = candidates[nearest_candidate(cm, x, xs, candidates)?] as usize;
    Some(locate_on_facet(cm, x, xs, facet))
}

/// [`locate`] once the nearest candidate facet (by the flat closest-point distance) is
/// known.
pub fn locate_on_facet(cm: &ContactModel, x: &[[f64; 3]], xs: [f64; 3], facet: usize) -> Located {
    locate_on_record(cm, x, xs, &CandidateFacet::of(cm, facet))
}

/// [`locate_on_facet`] with the facet's record at hand: its topology is read from there
/// (see [`super::candidate_facet`]), not from `cm`, except for the flat pseudo-normal at
/// a vertex (rare: asked for only where the patch does not decide).
#[inline(always)]
pub fn locate_on_record(
    cm: &ContactModel,
    x: &[[f64; 3]],
    xs: [f64; 3],
    facet: &CandidateFacet,
) -> Located {
    let [a, b, c] = facet.corners.map(|n| x[n as usize]);
    let cl = closest_point_on_triangle(xs, a, b, c);
    let d = sub(xs, cl.point);
    let dist = cl.dist2.sqrt();
    // The flat pseudo-normal's sign test is asked for only where the patch does not decide
    // (a flat facet, or a node beyond twice the patch's bulge): a contact node is well
    // within the bulge, and at a vertex this test costs an `acos` per facet of the ring.
    let flat_inside_along = |pn: [f64; 3]| dot(d, pn) < 0.0 && dist > 0.0;
    let flat_inside = || flat_inside_along(pseudo_normal(cm, x, facet, cl.feature));
    // a loop, not `map`: a closure would be compiled apart, without the caller's target
    // features (`super::prefetch::evaluate_pipelined`)
    let mut corners = [None; 3];
    for (k, normal) in corners.iter_mut().enumerate() {
        *normal = smooth_normal(x, facet.corners[k], facet.fan(cm, k));
    }
    if let Some(on_patch) = locate_on_patch(cm, x, &corners, xs, facet, cl, flat_inside) {
        return on_patch;
    }
    let pn = pseudo_normal(cm, x, facet, cl.feature);
    let (index, corners) = (facet.facet as usize, facet.corners);
    if !flat_inside_along(pn) {
        return Located {
            closest: cl,
            facet: index,
            corners,
            depth: -dist,
            normal: [0.0; 3],
        };
    }
    let (depth, normal) = match cl.feature {
        Feature::Face => {
            let n = scale(pn, 1.0 / norm(pn));
            (-dot(d, n), n)
        }
        _ => (dist, scale(d, -1.0 / dist)),
    };
    Located {
        closest: cl,
        facet: index,
        corners,
        depth,
        normal,
    }
}

/// The curved patch of a master facet, or `None` when it stays flat.
#[inline(always)]
fn facet_patch(
    x: &[[f64; 3]],
    corners: [u32; 3],
    vertex_normal: impl Fn(usize) -> Option<[f64; 3]>,
) -> Option<Patch> {
    let [a, b, c] = corners.map(|n| x[n as usize]);
    Patch::of_facet([a, b, c], triangle_normal(a, b, c), vertex_normal)
}

/// `xs` against the curved patch of `facet` (and of its neighbour across the edge the
/// closest patch point is clamped to), from the flat closest point `cl`. `None` when the
/// facet stays flat (a crease). Far outside (beyond the patch's bulge) the flat distance
/// less the bulge is returned: a lower bound of the patch distance, which is all the
/// broad phase needs. `flat_inside` (the flat pseudo-normal's sign test) is called only
/// there, beyond twice the bulge.
#[inline(always)]
fn locate_on_patch(
    cm: &ContactModel,
    x: &[[f64; 3]],
    corners: &[Option<[f64; 3]>; 3],
    xs: [f64; 3],
    facet: &CandidateFacet,
    cl: Closest,
    flat_inside: impl FnOnce() -> bool,
) -> Option<Located> {
    let patch = facet_patch(x, facet.corners, |k| corners[k])?;
    let dist = cl.dist2.sqrt();
    let bulge = patch.bulge_bound();
    let here = (facet.facet as usize, facet.corners);
    if dist > 2.0 * bulge && !flat_inside() {
        return Some(Located {
            closest: cl,
            facet: here.0,
            corners: here.1,
            depth: -(dist - bulge),
            normal: [0.0; 3],
        });
    }
    let mut best = (patch.closest(xs, cl.bary), here);
    if let Some(k) = best.0.clamped_edge {
        if let Some(other) = facet.across(k) {
            let o = facet.neighbours[k];
            // two of the neighbour's corners are this facet's, the third is the far one
            // (a loop, as above)
            let mut normals = [None; 3];
            for (normal, &v) in normals.iter_mut().zip(&o) {
                *normal = match facet.corners.iter().position(|&c| c == v) {
                    Some(i) => corners[i],
                    None => smooth_normal(x, v, facet.far_fan(cm, k)),
                };
            }
            if let Some(p) = facet_patch(x, o, |k| normals[k]) {
                let [a, b, c] = o.map(|n| x[n as usize]);
                let start = closest_point_on_triangle(xs, a, b, c).bary;
                let candidate = p.closest(xs, start);
                if candidate.distance < best.0.distance {
                    best = (candidate, (other, o));
                }
            }
        }
    }
    let (pp, (facet, corners)) = best;
    Some(Located {
        closest: Closest {
            point: pp.point,
            bary: pp.bary,
            feature: Feature::Face,
            dist2: pp.distance * pp.distance,
        },
        facet,
        corners,
        depth: pp.depth,
        normal: if pp.depth > 0.0 { pp.normal } else { [0.0; 3] },
    })
}

/// Evaluates one slave node against its candidate facets (see module docs). Pure function
/// of its inputs: safe to run in parallel, results independent of scheduling. Callers
/// evaluate only the entries that [`super::broad::CandidateLists::within_reach`] lists.
pub fn evaluate_entry(ctx: &EvalContext, entry: &Entry) -> PointResult {
    let mut history = HistoryCursor::default();
    evaluate_entry_on(ctx, entry, nearest_facet(ctx, entry), &mut history)
}

/// The candidate facet of `entry` nearest to its slave node (by the flat closest-point
/// distance), as an index into `ctx.facets`, `None` without candidates: the first step of
/// [`evaluate_entry`], which [`super::prefetch`] needs before the rest.
#[inline(always)]
pub fn nearest_facet(ctx: &EvalContext, entry: &Entry) -> Option<u32> {
    let cands = &ctx.facets[entry.start as usize..entry.end as usize];
    let xs = ctx.x[ctx.cm.node[entry.slave as usize] as usize];
    nearest_record(ctx.x, xs, cands).map(|i| entry.start + i as u32)
}

/// [`evaluate_entry`] with its [`nearest_facet`] already found; `history` finds the
/// friction point (fastest when entries come in order).
#[inline(always)]
pub fn evaluate_entry_on(
    ctx: &EvalContext,
    entry: &Entry,
    nearest: Option<u32>,
    history: &mut HistoryCursor,
) -> PointResult {
    let cm = ctx.cm;
    let x = ctx.x;
    let s_flat = entry.slave as usize;
    let s = cm.node[s_flat];
    let mut r = PointResult {
        slave: s,
        pass: entry.pass,
        ..Default::default()
    };
    let xs = x[s as usize];
    let Some(nearest) = nearest else {
        r.separation = f64::INFINITY;
        return r;
    };
    let record = &ctx.facets[nearest as usize];
    let loc = locate_on_record(cm, x, xs, record);
    if loc.depth <= 0.0 {
        r.separation = -loc.depth;
        return r;
    }
    let (cl, facet, gap, normal) = (loc.closest, loc.facet, loc.depth, loc.normal);
    let pass = ctx.passes[entry.pass as usize];
    let (sg, mg) = (
        &cm.surfaces[pass.slave as usize],
        &cm.surfaces[pass.master as usize],
    );
    let masters = loc.corners;
    // the record knows where its corners' edges are; a neighbour's are looked up
    let slots = if facet == record.facet as usize {
        record.slots
    } else {
        masters.map(|m| cm.surface_index[m as usize])
    };
    let h_s = cm.node_h[s_flat];
    let mut h_m = 0.0;
    for (i, &slot) in slots.iter().enumerate() {
        h_m += cl.bary[i] * cm.node_h[slot as usize];
    }
    let eps = cm.penalty(sg.e_prime.max(mg.e_prime), h_s, h_m);
    let area = cm.node_area[s_flat] * PASS_WEIGHT;
    let pressure = eps * gap;
    let mut vm = [0.0; 3];
    for (i, &m) in masters.iter().enumerate() {
        vm = add(vm, scale(ctx.v[m as usize], cl.bary[i]));
    }
    let v_rel = sub(ctx.v[s as usize], vm);
    // Normal damping c ġ, c = 2ζ√(k m_s), ġ = −v_rel·n; never pulling (no adhesion).
    let mut damping_force = 0.0;
    if cm.damping > 0.0 && !ctx.mass.is_empty() {
        let c = 2.0 * cm.damping * (eps * area * ctx.mass[s as usize]).sqrt();
        damping_force = (-c * dot(v_rel, normal)).max(-pressure * area);
    }
    let mut force = scale(normal, pressure * area + damping_force);
    let mut energy = 0.5 * pressure * gap * area;
    let mut dissipation = 0.0;
    let mut traction = [0.0; 3];
    let mut sliding = false;
    if ctx.friction {
        let key = ContactKey::of(sg, mg, s);
        let t_old = match history.find(ctx.history, key) {
            Some(p) => rotate_onto_plane(p.traction, normal),
            None => [0.0; 3],
        };
        let du = scale(v_rel, ctx.dt);
        let du_t = tangential(du, normal);
        let eps_t = eps; // ε_t = ε_n (see module docs of `contact`)
        let rm = return_map(t_old, du_t, eps_t, cm.friction * pressure);
        traction = rm.traction;
        force = add(force, scale(traction, area));
        energy += 0.5 * dot(traction, traction) / eps_t * area;
        dissipation = rm.dissipation * area;
        sliding = !rm.sticking;
    }
    r.active = true;
    r.tunnel = gap > 0.5 * h_s;
    r.masters = masters;
    r.weights = cl.bary;
    r.force = force;
    r.gap = gap;
    r.normal = normal;
    r.pressure = pressure;
    r.penalty = eps;
    r.area = area;
    r.damping_force = damping_force;
    r.energy = energy;
    r.dissipation = dissipation;
    r.traction = traction;
    r.sliding = sliding;
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cursor finds what a binary search finds: keys asked in ascending order (its
    /// use), in descending order and at random, present or not, from any history length.
    #[test]
    fn history_cursor_finds_what_a_binary_search_finds() {
        let key = |grain: u32, node: u32| ContactKey {
            grain,
            other: grain + 1,
            image: [0; 3],
            other_image: [0; 3],
            node,
        };
        let mut seed = 12345u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for len in [0usize, 1, 2, 7, 100, 1000] {
            let mut history: Vec<FrictionPoint> = (0..len)
                .map(|_| FrictionPoint {
                    key: key(next() % 4, next() % 500),
                    traction: [next() as f64; 3],
                })
                .collect();
            history.sort_by_key(|p| p.key);
            history.dedup_by_key(|p| p.key);
            let mut asked: Vec<ContactKey> =
                (0..300).map(|_| key(next() % 5, next() % 520)).collect();
            asked.extend(history.iter().step_by(3).map(|p| p.key));
            let mut ascending = asked.clone();
            ascending.sort();
            let mut descending = ascending.clone();
            descending.reverse();
            for order in [&ascending, &descending, &asked] {
                let mut cursor = HistoryCursor::default();
                let mut found = 0;
                for &k in order {
                    let expected = history.binary_search_by_key(&k, |p| p.key).ok();
                    let got = cursor.find(&history, k);
                    assert_eq!(
                        got.map(|p| p.key),
                        expected.map(|i| history[i].key),
                        "{k:?}"
                    );
                    found += usize::from(got.is_some());
                }
                assert!(found >= history.len().div_ceil(3), "{found} found");
            }
        }
    }

    #[test]
    fn bvh_query_matches_brute_force() {
        // A strip of triangles; query boxes at random places.
        let mut facet = Vec::new();
        let mut x = Vec::new();
        for i in 0..40 {
            let f = i as f64;
            x.push([f, 0.0, (f * 0.3).sin()]);
            x.push([f, 1.0, (f * 0.3).cos()]);
        }
        for i in 0..39u32 {
            facet.push([2 * i, 2 * i + 2, 2 * i + 1]);
            facet.push([2 * i + 1, 2 * i + 2, 2 * i + 3]);
        }
        let cm = ContactModel {
            facet: facet.clone(),
            ..Default::default()
        };
        let mut bvh = Bvh::default();
        bvh.build(&cm, 0..facet.len(), &x);
        let mut out = Vec::new();
        for k in 0..50 {
            let c = [k as f64 * 0.8 - 1.0, 0.5, 0.0];
            let q = Aabb::around(c, 0.7);
            out.clear();
            bvh.query(&q, &mut out);
            let brute: Vec<u32> = (0..facet.len() as u32)
                .filter(|&f| {
                    let mut b = Aabb::EMPTY;
                    for &n in &facet[f as usize] {
                        b.grow(x[n as usize]);
                    }
                    b.overlaps(&q)
                })
                .collect();
            assert_eq!(out, brute, "query {k}");
        }
    }
}
