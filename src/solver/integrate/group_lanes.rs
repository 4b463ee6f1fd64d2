//! The node update of the register groups ([`super::groups_avx512`],
//! [`super::groups_avx2`]), written once over a register of f64 lanes ([`Register`]):
//! each group module supplies its register's loads, stores and arithmetic, and how it
//! sorts records of three f64 into components and back.
//!
//! Every lane evaluates the expressions of [`super::update_node`] in its order, with no
//! fused multiply–add, so x, v and the lane sums are the same to the bit
//! (`a_group_of_lanes_is_its_nodes_one_by_one_to_the_bit` runs every path the CPU has).
//!
//! Everything here is `#[inline(always)]` and reached only from the groups'
//! `#[target_feature]` functions: inlined there, the intrinsics inherit those features. A
//! closure is compiled apart, without them, and its intrinsics became calls
//! (docs/BENCHMARKS.md, session 76); `objdump` of both `update_group`s shows no call but
//! the cold panics.

use super::{GroupForces, Inputs, LaneSums, LANES};

/// A register of `WIDTH` f64 lanes. Every method is a single instruction or a fixed
/// shuffle sequence of the register's instruction set.
pub(super) trait Register: Copy {
    /// f64 lanes per register.
    const WIDTH: usize;
    /// [`Register::finite_lanes`] of a register whose every lane is finite.
    const ALL_FINITE: u32;
    unsafe fn splat(value: f64) -> Self;
    unsafe fn load(p: *const f64) -> Self;
    unsafe fn store(p: *mut f64, value: Self);
    unsafe fn add(a: Self, b: Self) -> Self;
    unsafe fn mul(a: Self, b: Self) -> Self;
    unsafe fn div(a: Self, b: Self) -> Self;
    /// Lane by lane: `a` where a > b, else `b`.
    unsafe fn max(a: Self, b: Self) -> Self;
    unsafe fn abs(self) -> Self;
    /// One bit per lane, set where the lane is finite (its difference with itself is 0).
    unsafe fn finite_lanes(self) -> u32;
    /// The x, y, z of `WIDTH` consecutive records of three f64 at `p`, one register each.
    unsafe fn load_components(p: *const f64) -> [Self; 3];
    /// The inverse of [`Register::load_components`].
    unsafe fn store_components(p: *mut f64, components: [Self; 3]);
    /// The x, y, z of `WIDTH` consecutive padded forces (four f64 each) at `p`.
    unsafe fn load_forces(p: *const f64) -> [Self; 3];
}

/// `math::dot` lane by lane: (p₀q₀ + p₁q₁) + p₂q₂.
#[inline(always)]
unsafe fn dot<R: Register>(p: &[R; 3], q: &[R; 3]) -> R {
    R::add(
        R::add(R::mul(p[0], q[0]), R::mul(p[1], q[1])),
        R::mul(p[2], q[2]),
    )
}

/// `*lanes += value`, lane by lane.
#[inline(always)]
unsafe fn add_to<R: Register>(lanes: *mut f64, value: R) {
    R::store(lanes, R::add(R::load(lanes), value));
}

/// Nodes `first..first + R::WIDTH` (`x`, `v`), none with a stored v_{n+½}, in a step
/// whose body forces are `forces` ([`GroupForces::of`] the step's): what
/// [`super::update_node`] does to each, node first + l into lane at + l of `sums`.
///
/// # Safety
/// The CPU must have `R`'s instructions; `x` and `v` hold at least `R::WIDTH` nodes,
/// `inputs` holds nodes up to first + `R::WIDTH`, and at + `R::WIDTH` ≤ [`LANES`].
#[inline(always)]
pub(super) unsafe fn update_lanes<R: Register>(
    inputs: &Inputs,
    first: usize,
    at: usize,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    sums: &mut LaneSums,
    forces: GroupForces,
) {
    debug_assert!(x.len() >= R::WIDTH && v.len() >= R::WIDTH && at + R::WIDTH <= LANES);
    let dt = R::splat(inputs.dt);
    let m = R::load(inputs.mass.as_ptr().add(first));
    let a = R::load_components(v.as_ptr().cast());
    let mut f = R::load_forces(inputs.force.as_ptr().add(first).cast());
    let mut fd = [R::splat(0.0); 3];
    if let GroupForces::MassDamped(alpha) = forces {
        // BodyForces::total_force: f + (w + f_d), f_d = −α m v, w = 0 without gravity
        let am = R::mul(R::splat(-alpha), m);
        let w = R::splat(0.0);
        for i in 0..3 {
            fd[i] = R::mul(am, a[i]);
            f[i] = R::add(f[i], R::add(w, fd[i]));
        }
    }
    // predict_along: v + dt·f / m
    let mut b = [R::splat(0.0); 3];
    for i in 0..3 {
        b[i] = R::add(a[i], R::div(R::mul(dt, f[i]), m));
    }
    // LaneSums::add: ½ m (a·b), then the largest |b| component by component
    let kinetic = R::mul(R::mul(R::splat(0.5), m), dot(&a, &b));
    add_to(sums.kinetic.as_mut_ptr().add(at), kinetic);
    let fastest = sums.max_speed.as_mut_ptr().add(at);
    let mut max = R::load(fastest);
    for c in b {
        // max(|c|, max) is |c| where |c| > max, else max: the `if` of LaneSums::add
        max = R::max(c.abs(), max);
    }
    R::store(fastest, max);
    if let GroupForces::MassDamped(_) = forces {
        add_to(sums.damping_before.as_mut_ptr().add(at), dot(&fd, &a));
        add_to(sums.damping_after.as_mut_ptr().add(at), dot(&fd, &b));
    }
    let mut finite = R::ALL_FINITE;
    for c in b {
        finite &= c.finite_lanes();
    }
    if finite != R::ALL_FINITE {
        let mut lanes = [[0.0; LANES]; 3];
        for (lanes, c) in lanes.iter_mut().zip(b) {
            R::store(lanes.as_mut_ptr(), c);
        }
        for l in 0..R::WIDTH {
            sums.check_finite(first + l, &[lanes[0][l], lanes[1][l], lanes[2][l]]);
        }
    }
    let p = x.as_mut_ptr().cast::<f64>();
    let xs = R::load_components(p);
    let mut moved = xs;
    for i in 0..3 {
        moved[i] = R::add(xs[i], R::mul(dt, b[i]));
    }
    R::store_components(p, moved);
    R::store_components(v.as_mut_ptr().cast(), b);
}
