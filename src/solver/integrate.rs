//! The integrator: x_{n+1} = x_n + Δt v_{n+½}, v ← v_{n+½}, with the step's kinetic energy,
//! body-force powers and largest speed summed over the nodes on the way.
//!
//! Nodes are updated eight at a time in lanes (one array per component), so that the
//! divisions by the mass and the damping force become vector instructions: node by node,
//! three scalar divisions and the damping arithmetic per node made the pass of the damped
//! 2000-sphere block compute-bound (4.4 ms/step against 3.0 without damping, the pass then
//! moving ≈ 130 B per node; docs/BENCHMARKS.md, session 36). Every lane evaluates the
//! expressions of [`crate::kinematics`] in the same order, so x and v are the same to the
//! bit as node by node. The sums go to one partial per lane ([`LaneSums`]: node k of a
//! chunk to partial k mod 8, on every path), added in lane order at the chunk's end:
//! summed node by node in node order, a scalar chain through every node, they were 40 %
//! of the pass on the damped 2000-sphere block (docs/BENCHMARKS.md, session 48). A group
//! with a node whose v_{n+½} a motion or wall stored goes node by node. In a step with no
//! gravity and no deformation damping the AVX-512 and AVX2 paths sort a group into
//! registers with full loads and permutes ([`groups_avx512`], [`groups_avx2`]) instead
//! of building the lanes element by element (docs/BENCHMARKS.md, sessions 76 and 77).

use super::damping::body_forces;
use super::forces::{KernelPath, NODE_CHUNK};
use super::state::State;
use crate::kinematics::{
    predict, predict_along, with_body_force, BodyForces, NextVelocity, RigidVelocity,
};
use crate::lanes::NodeForce;
use crate::math::dot;
use crate::model::Model;
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
mod group_lanes;
#[cfg(target_arch = "x86_64")]
mod groups_avx2;
#[cfg(target_arch = "x86_64")]
mod groups_avx512;

/// Nodes per group of lanes.
const LANES: usize = 8;
// a chunk starts a group, so node k of a chunk is lane k mod LANES of its group
const _: () = assert!(NODE_CHUNK.is_multiple_of(LANES));

/// One chunk's sums (added over the chunks in order).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct NodePartials {
    pub kinetic: f64,
    pub gravity_before: f64,
    pub gravity_after: f64,
    pub damping_before: f64,
    pub damping_after: f64,
    /// Largest velocity component |v_{n+½}|_∞ (m/s): √3 Δt times it bounds how far any
    /// node went in the step.
    pub max_speed: f64,
    pub bad_node: Option<usize>,
}

/// Which register group a path's chunks hand their groups to, and with what body force.
#[derive(Debug, Clone, Copy, PartialEq)]
enum InRegisters {
    Avx512(GroupForces),
    Avx2(GroupForces),
}

/// The body force a step's groups may have for the register groups
/// (`groups_avx512::update_group`, `groups_avx2::update_group`) to take them.
#[derive(Debug, Clone, Copy, PartialEq)]
enum GroupForces {
    /// None at all.
    Free,
    /// −α m v only (α, 1/s).
    MassDamped(f64),
}

impl GroupForces {
    /// The group forces of a step with body forces `body`; `None` when the register
    /// groups cannot take them (gravity, or damping of deformation).
    fn of(body: Option<&BodyForces>) -> Option<Self> {
        match body {
            None => Some(Self::Free),
            Some(b) if !b.weighs() && b.deformation_damping <= 0.0 => {
                Some(Self::MassDamped(b.alpha))
            }
            Some(_) => None,
        }
    }
}

/// What every node's update reads besides its own x and v.
struct Inputs<'a> {
    mass: &'a [f64],
    force: &'a [NodeForce],
    next: &'a NextVelocity,
    body: Option<BodyForces<'a>>,
    weighs: bool,
    dt: f64,
}

/// One chunk's sums by lane: node k of the chunk adds to lane k mod [`LANES`] of each,
/// whichever path updates it (a group of lanes adds eight nodes in vector instructions,
/// a node alone adds to its own lane), so the sums are the same on every path and thread
/// count; [`LaneSums::total`] adds the lanes in order.
#[derive(Debug, Clone, Copy, Default)]
struct LaneSums {
    kinetic: [f64; LANES],
    gravity_before: [f64; LANES],
    gravity_after: [f64; LANES],
    damping_before: [f64; LANES],
    damping_after: [f64; LANES],
    max_speed: [f64; LANES],
    bad_node: Option<usize>,
}

/// A node's terms for the sums: v_{n−½} = `a`, v_{n+½} = `b`, mass `m`, damping force
/// `fd` and gravity force `w` = m_physical g. Without body forces `fd` is not read, and
/// without gravity `w` is not: [`LaneSums::add`] leaves those powers at +0, whatever the
/// node does (0 · ∞ would not be).
struct NodeTerms {
    m: f64,
    a: [f64; 3],
    b: [f64; 3],
    fd: [f64; 3],
    w: [f64; 3],
}

impl LaneSums {
    /// Adds a node's terms `t` to lane `l`, with the flags of what the step has: damping
    /// (`body`) and gravity (`weighs`).
    #[inline(always)]
    fn add(&mut self, l: usize, t: &NodeTerms, body: bool, weighs: bool) {
        let NodeTerms { m, a, b, fd, w } = t;
        self.kinetic[l] += 0.5 * m * dot(*a, *b);
        // plain comparisons (one max instruction each): no NaN handling is needed here,
        // see bad_node
        for c in b {
            let c = c.abs();
            if c > self.max_speed[l] {
                self.max_speed[l] = c;
            }
        }
        if body {
            if weighs {
                self.gravity_before[l] += dot(*w, *a);
                self.gravity_after[l] += dot(*w, *b);
            }
            self.damping_before[l] += dot(*fd, *a);
            self.damping_after[l] += dot(*fd, *b);
        }
    }

    /// Records node `n` if it is the chunk's first with a non-finite v_{n+½}.
    #[inline(always)]
    fn check_finite(&mut self, n: usize, b: &[f64; 3]) {
        if self.bad_node.is_none() && !(b[0].is_finite() && b[1].is_finite() && b[2].is_finite()) {
            self.bad_node = Some(n);
        }
    }

    /// The chunk's sums: each over the lanes in lane order.
    fn total(&self) -> NodePartials {
        let sum = |v: &[f64; LANES]| v.iter().fold(0.0, |s, x| s + x);
        NodePartials {
            kinetic: sum(&self.kinetic),
            gravity_before: sum(&self.gravity_before),
            gravity_after: sum(&self.gravity_after),
            damping_before: sum(&self.damping_before),
            damping_after: sum(&self.damping_after),
            max_speed: self.max_speed.iter().fold(0.0, |s, &x| s.max(x)),
            bad_node: self.bad_node,
        }
    }
}

/// What the step hands the integrator besides the model and the state.
pub(super) struct StepResults<'a> {
    /// Node forces from elements and contacts (N).
    pub force: &'a [NodeForce],
    /// The v_{n+½} that motions and walls stored.
    pub next: &'a NextVelocity,
    /// Each grain's rigid velocity (for deformation damping).
    pub rigid: &'a [RigidVelocity],
    /// The element kernel's compiled path, which the node update shares.
    pub path: KernelPath,
}

/// Kinetic energy and power sums over the owned nodes (fixed chunks, one entry of
/// `partials` each, summed in order), then x_{n+1} = x_n + Δt v_{n+½} and v ← v_{n+½}.
pub(super) fn integrate_and_sum(
    model: &Model,
    alpha: f64,
    g: [f64; 3],
    state: &mut State,
    step: StepResults,
    partials: &mut [NodePartials],
    dt: f64,
) -> NodePartials {
    let body = body_forces(model, alpha, g, step.rigid);
    let inputs = Inputs {
        mass: &model.mass,
        force: step.force,
        next: step.next,
        weighs: body.is_some_and(|b| b.weighs()),
        body,
        dt,
    };
    let owned = model.owned_nodes;
    let path = step.path;
    state.x[..owned]
        .par_chunks_mut(NODE_CHUNK)
        .zip(state.v[..owned].par_chunks_mut(NODE_CHUNK))
        .zip(partials.par_iter_mut())
        .enumerate()
        .for_each(|(chunk, ((x, v), out))| {
            *out = integrate_chunk_on(path, &inputs, chunk * NODE_CHUNK, x, v);
        });
    let mut total = NodePartials::default();
    for p in partials.iter() {
        total.kinetic += p.kinetic;
        total.gravity_before += p.gravity_before;
        total.gravity_after += p.gravity_after;
        total.damping_before += p.damping_before;
        total.damping_after += p.damping_after;
        total.max_speed = total.max_speed.max(p.max_speed);
        if total.bad_node.is_none() {
            total.bad_node = p.bad_node;
        }
    }
    total
}

/// [`integrate_chunk`] compiled for the element kernel's path (`path` is one the CPU
/// runs: [`KernelPath::detect`]), whose wider lanes divide eight or four masses at once.
fn integrate_chunk_on(
    path: KernelPath,
    inputs: &Inputs,
    base: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
) -> NodePartials {
    match path {
        // SAFETY: the path was detected on this CPU
        #[cfg(target_arch = "x86_64")]
        KernelPath::Avx512 => unsafe { integrate_chunk_avx512(inputs, base, x, v) },
        // SAFETY: the same
        #[cfg(target_arch = "x86_64")]
        KernelPath::Avx2 => unsafe { integrate_chunk_avx2(inputs, base, x, v) },
        _ => integrate_chunk(inputs, base, x, v, None),
    }
}

/// [`integrate_chunk`] for AVX-512.
///
/// # Safety
/// The CPU must support AVX-512F and VL ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
unsafe fn integrate_chunk_avx512(
    inputs: &Inputs,
    base: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
) -> NodePartials {
    let in_registers = GroupForces::of(inputs.body.as_ref()).map(InRegisters::Avx512);
    integrate_chunk(inputs, base, x, v, in_registers)
}

/// [`integrate_chunk`] for AVX2.
///
/// # Safety
/// The CPU must support AVX2 and FMA ([`KernelPath::detect`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn integrate_chunk_avx2(
    inputs: &Inputs,
    base: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
) -> NodePartials {
    let in_registers = GroupForces::of(inputs.body.as_ref()).map(InRegisters::Avx2);
    integrate_chunk(inputs, base, x, v, in_registers)
}

/// The nodes `base..` of one chunk (`x`, `v`; `base` a multiple of [`LANES`]): groups of
/// [`LANES`] aligned to the chunk, node by node where a group has a stored v_{n+½} and
/// at the chunk's end. A group goes through AVX-512 or AVX2 registers when
/// `in_registers` says which and what body forces it has (only the AVX-512 and AVX2 paths,
/// compiled for those instructions, say it).
#[inline(always)]
fn integrate_chunk(
    inputs: &Inputs,
    base: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    in_registers: Option<InRegisters>,
) -> NodePartials {
    debug_assert!(base.is_multiple_of(LANES));
    let mut sums = LaneSums::default();
    let groups = x.len() / LANES;
    for (g, (x, v)) in (x.chunks_exact_mut(LANES))
        .zip(v.chunks_exact_mut(LANES))
        .enumerate()
    {
        let n = base + g * LANES;
        if inputs.next.any_stored(n..n + LANES) {
            for (l, (x, v)) in x.iter_mut().zip(v.iter_mut()).enumerate() {
                update_node(inputs, n + l, l, x, v, &mut sums);
            }
        } else {
            #[cfg(target_arch = "x86_64")]
            match in_registers {
                Some(InRegisters::Avx512(forces)) => {
                    // SAFETY: only the AVX-512 path, run on a CPU found to have AVX-512,
                    // names it; the group has LANES nodes, all in `inputs`
                    unsafe { groups_avx512::update_group(inputs, n, x, v, &mut sums, forces) };
                    continue;
                }
                Some(InRegisters::Avx2(forces)) => {
                    // SAFETY: the same for the AVX2 path and AVX2
                    unsafe { groups_avx2::update_group(inputs, n, x, v, &mut sums, forces) };
                    continue;
                }
                None => {}
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = in_registers;
            update_group(inputs, n, x, v, &mut sums);
        }
    }
    let first = groups * LANES;
    for (k, (x, v)) in x[first..].iter_mut().zip(&mut v[first..]).enumerate() {
        update_node(inputs, base + first + k, k, x, v, &mut sums);
    }
    sums.total()
}

/// Node `n` alone, into lane `l` of the sums: the complete force and v_{n+½} as every
/// reader in the step had them (`crate::kinematics`), the damping force once for both the
/// velocity and its power.
#[inline(always)]
fn update_node(
    inputs: &Inputs,
    n: usize,
    l: usize,
    x: &mut [f64; 3],
    v: &mut [f64; 3],
    sums: &mut LaneSums,
) {
    let m = inputs.mass[n];
    let a = *v;
    let (f, fd) = match &inputs.body {
        None => (inputs.force[n].xyz(), [0.0; 3]),
        Some(body) => body.total_force(n, inputs.force[n].xyz(), x, &a, m),
    };
    let b = (inputs.next.stored(n)).unwrap_or_else(|| predict(a, f, m, inputs.dt));
    let w = (inputs.body.as_ref()).map_or([0.0; 3], |body| body.weight(n));
    let terms = NodeTerms { m, a, b, fd, w };
    sums.add(l, &terms, inputs.body.is_some(), inputs.weighs);
    sums.check_finite(n, &b);
    for i in 0..3 {
        x[i] += inputs.dt * b[i];
    }
    *v = b;
}

/// Nodes `n..n + LANES` (`x`, `v`), none with a stored v_{n+½}: the expressions of
/// [`update_node`] lane by lane, node n + l into lane l of the sums.
#[inline(always)]
fn update_group(
    inputs: &Inputs,
    n: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    sums: &mut LaneSums,
) {
    type Lanes = [f64; LANES];
    use std::array::from_fn;
    let m: Lanes = from_fn(|l| inputs.mass[n + l]);
    let a: [Lanes; 3] = from_fn(|i| from_fn(|l| v[l][i]));
    let node_force: [[f64; 4]; LANES] = from_fn(|l| inputs.force[n + l].padded());
    let mut f: [Lanes; 3] = from_fn(|i| from_fn(|l| node_force[l][i]));
    let mut fd = [[0.0; LANES]; 3];
    let mut w = [[0.0; LANES]; 3];
    if let Some(body) = &inputs.body {
        // BodyForces::total_force, lane by lane
        for i in 0..3 {
            for l in 0..LANES {
                fd[i][l] = body.mass_damping_along(m[l], a[i][l]);
            }
        }
        if body.deformation_damping > 0.0 {
            let rigid: [[f64; 3]; LANES] =
                from_fn(|l| body.rigid[body.node_grain[n + l] as usize].at(&x[l]));
            for i in 0..3 {
                for l in 0..LANES {
                    let (f, v) = (fd[i][l], a[i][l]);
                    fd[i][l] = body.add_deformation_damping(f, m[l], v, rigid[l][i]);
                }
            }
        }
        if inputs.weighs {
            let mp: Lanes = from_fn(|l| body.physical_mass[n + l]);
            for i in 0..3 {
                for l in 0..LANES {
                    w[i][l] = mp[l] * body.gravity[i];
                }
            }
        }
        for i in 0..3 {
            for l in 0..LANES {
                f[i][l] = with_body_force(f[i][l], w[i][l], fd[i][l]);
            }
        }
    }
    let dt = inputs.dt;
    let mut b = [[0.0; LANES]; 3];
    for i in 0..3 {
        for l in 0..LANES {
            b[i][l] = predict_along(a[i][l], f[i][l], m[l], dt);
        }
    }
    let node = |c: &[Lanes; 3], l: usize| [c[0][l], c[1][l], c[2][l]];
    let (body, weighs) = (inputs.body.is_some(), inputs.weighs);
    for l in 0..LANES {
        let terms = NodeTerms {
            m: m[l],
            a: node(&a, l),
            b: node(&b, l),
            fd: node(&fd, l),
            w: node(&w, l),
        };
        sums.add(l, &terms, body, weighs);
    }
    // one test for the group (the lanes' flags and-ed, no early exit), node by node only
    // when it fails
    let finite = (b.iter().flatten()).fold(true, |all, c| all & c.is_finite());
    if !finite {
        for l in 0..LANES {
            sums.check_finite(n + l, &node(&b, l));
        }
    }
    for (l, (x, v)) in x.iter_mut().zip(v.iter_mut()).enumerate() {
        for i in 0..3 {
            x[i] += dt * b[i][l];
        }
        *v = node(&b, l);
    }
}

/// Asserts that `components` (x, y, z, one array of lanes each) hold what the register
/// groups' unit tests load: lane l of component i is element `record × l + i` of records
/// numbered 0, 1, 2, …, `record` f64 each.
#[cfg(all(test, target_arch = "x86_64"))]
fn assert_sorted_into_components<const W: usize>(components: [[f64; W]; 3], record: usize) {
    for (i, lanes) in components.iter().enumerate() {
        for (l, &value) in lanes.iter().enumerate() {
            assert_eq!(value, (record * l + i) as f64, "component {i}, lane {l}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::RigidVelocity;

    /// The first node with a non-finite v_{n+½} is reported, whether it is in a group of
    /// lanes, in a group that goes node by node or alone at the chunk's end, on every
    /// kernel path this CPU runs.
    #[test]
    fn the_first_non_finite_velocity_is_the_bad_node() {
        const NODES: usize = 21;
        let mass = vec![1e-9; NODES];
        for path in KernelPath::ALL.into_iter().filter(|p| p.is_supported()) {
            // [first, second, a node with a stored v_{n+½}, whose group goes node by node]
            for bad in [
                [5, 13, 0],
                [18, 20, 0],
                [19, 3, 0],
                [12, 10, 11],
                [14, 9, 13],
            ] {
                let mut stored = NextVelocity::new(NODES);
                if bad[2] > 0 {
                    stored.set(bad[2], [0.5, -0.25, 0.125]);
                }
                let mut force = vec![NodeForce::from([1e-3, -2e-3, 5e-4]); NODES];
                force[bad[0]][1] = f64::NAN;
                force[bad[1]][2] = f64::INFINITY;
                let inputs = Inputs {
                    mass: &mass,
                    force: &force,
                    next: &stored,
                    weighs: false,
                    body: None,
                    dt: 1e-9,
                };
                let (mut x, mut v) = (vec![[0.0; 3]; NODES], vec![[0.0; 3]; NODES]);
                let p = integrate_chunk_on(path, &inputs, 0, &mut x, &mut v);
                assert_eq!(p.bad_node, Some(bad[0].min(bad[1])), "{path:?} {bad:?}");
            }
        }
    }

    /// Nodes in lanes give what they give one by one, to the bit: x, v and every sum,
    /// without body forces, with mass damping, with deformation damping and with gravity
    /// (each on top of the last), over velocities, forces and masses spanning decades, on
    /// every kernel path this CPU runs; 21 nodes, one with a stored v_{n+½}, so that a
    /// group goes node by node and the chunk ends in single nodes. The kinetic energy is
    /// the node-order sum to rounding, and the largest speed exactly.
    #[test]
    fn a_group_of_lanes_is_its_nodes_one_by_one_to_the_bit() {
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let scale = |r: f64, decades: f64| 10f64.powf(r * decades);
        let rigid = [
            RigidVelocity {
                centre: [1e-3, -2e-3, 5e-4],
                velocity: [0.3, -0.1, 0.02],
                omega: [12.0, -3.0, 40.0],
            },
            RigidVelocity {
                centre: [-1e-3, 2e-3, 0.0],
                velocity: [-0.2, 0.05, 0.4],
                omega: [-5.0, 8.0, 1.0],
            },
        ];
        const NODES: usize = 21;
        let node_grain: Vec<u32> = (0..NODES as u32).map(|l| l % 3 / 2).collect();
        let paths: Vec<KernelPath> = (KernelPath::ALL.into_iter())
            .filter(|p| p.is_supported())
            .collect();
        for trial in 0..200 {
            let mass: Vec<f64> = (0..NODES).map(|_| 1e-9 * scale(next(), 3.0)).collect();
            let physical: Vec<f64> = mass.iter().map(|m| m * (0.9 + 0.1 * next())).collect();
            let force: Vec<NodeForce> = (0..NODES)
                .map(|_| {
                    [next(), next(), next()]
                        .map(|c| c * scale(next(), 4.0))
                        .into()
                })
                .collect();
            let x0: Vec<[f64; 3]> = (0..NODES)
                .map(|_| [next(), next(), next()].map(|c| 2e-3 * c))
                .collect();
            let v0: Vec<[f64; 3]> = (0..NODES)
                .map(|_| [next(), next(), next()].map(|c| c * scale(next(), 2.0)))
                .collect();
            let body = |alpha: f64, dd: f64, g: [f64; 3]| BodyForces {
                gravity: g,
                alpha,
                deformation_damping: dd,
                physical_mass: &physical,
                node_grain: &node_grain,
                rigid: &rigid,
            };
            let cases = [
                None,
                Some(body(3e4, 0.0, [0.0; 3])),
                Some(body(3e4, 2e5, [0.0; 3])),
                Some(body(3e4, 2e5, [0.0, 0.0, -9.81])),
            ];
            let mut stored = NextVelocity::new(NODES);
            stored.set(11, [0.5, -0.25, 0.125]);
            for body in cases {
                let inputs = Inputs {
                    mass: &mass,
                    force: &force,
                    next: &stored,
                    weighs: body.is_some_and(|b| b.weighs()),
                    body,
                    dt: 5.5e-9 * (1.0 + 0.5 * next()),
                };
                let (mut xn, mut vn, mut sn) = (x0.clone(), v0.clone(), LaneSums::default());
                for l in 0..NODES {
                    update_node(&inputs, l, l % LANES, &mut xn[l], &mut vn[l], &mut sn);
                }
                let pn = sn.total();
                // the lane sums are the node sums, regrouped
                let kinetic: f64 = (0..NODES).map(|k| 0.5 * mass[k] * dot(v0[k], vn[k])).sum();
                let scale: f64 = (0..NODES)
                    .map(|k| (0.5 * mass[k] * dot(v0[k], vn[k])).abs())
                    .sum();
                assert!(
                    (pn.kinetic - kinetic).abs() <= 1e-14 * scale,
                    "trial {trial}"
                );
                let fastest = vn.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
                assert_eq!(pn.max_speed, fastest);
                for &path in &paths {
                    let (mut xg, mut vg) = (x0.clone(), v0.clone());
                    let pg = integrate_chunk_on(path, &inputs, 0, &mut xg, &mut vg);
                    let bits = |v: &[[f64; 3]]| -> Vec<u64> {
                        v.iter().flatten().map(|c| c.to_bits()).collect()
                    };
                    assert_eq!(bits(&xg), bits(&xn), "x, trial {trial}, {path:?}");
                    assert_eq!(bits(&vg), bits(&vn), "v, trial {trial}, {path:?}");
                    assert_ne!(bits(&vg), bits(&v0), "v moved");
                    let sums = |p: &NodePartials| {
                        [
                            p.kinetic,
                            p.gravity_before,
                            p.gravity_after,
                            p.damping_before,
                            p.damping_after,
                            p.max_speed,
                        ]
                        .map(f64::to_bits)
                    };
                    assert_eq!(sums(&pg), sums(&pn), "sums, trial {trial}, {path:?}");
                    assert_eq!(pg.bad_node, pn.bad_node);
                }
            }
        }
    }
}
