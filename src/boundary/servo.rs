//! Servo-controlled rigid walls: a wall that moves along its normal so that the normal
//! force it exerts on the grains holds a target F* = σ* A (σ* the target stress, A the area
//! it acts on).
//!
//! # Control law
//! The wall is kinematic (massless, no inertia of its own). Its normal displacement s (m,
//! positive along the inward normal n, i.e. into the grains) advances with
//!
//! ```text
//! s_{n+1} = s_n + Δt v_{n+½},     v_{n+½} = clamp(G (e_n + I_n/τ_I), ±v_max),
//! e_n = F* − F̄_n,   I_n = Σ Δt e (only while F̄ > 0 and v is not clamped),
//! F̄_n     = F̄_{n−1} + Δt/(τ_f + Δt) (F_n − F̄_{n−1}),   G = 1/(k τ),  τ_f = τ/32,  τ_I = 8τ,
//! ```
//!
//! where F_n = f_n·n is the measured normal force of step n summed over all ranks (the
//! same number on every rank, so all ranks move the wall identically), F̄ its first-order
//! low-pass filter (the kinematic wall force is the arrest of single nodes: it jumps from
//! step to step, and an unfiltered integral controller would feed that noise into the
//! wall's motion), k an estimate of the stiffness dF/ds the wall sees at the target load
//! and τ the time constant of the closed loop.
//!
//! In a stage where other walls strain the specimen at a prescribed speed (`tracking`),
//! an integral term is added; without it (isotropic compression, a lone servo wall) the
//! law is the proportional one above, with I = 0. The integral term makes the loop follow a specimen that keeps yielding at a steady
//! rate (the lateral walls of a triaxial test while the axial wall advances: the wall must
//! keep moving at the speed v the specimen needs) with no steady error; with the
//! proportional term alone the error would stay at v/(G F*) = v k τ/F*. It learns that
//! speed over τ_I; it is frozen while the wall has nothing to push against (the approach)
//! and while the speed is clamped, so that it cannot wind up.
//!
//! # Stability
//! Quasi-statically the packing answers F = F(s) with tangent stiffness k_true. Writing
//! e = F̄ − F*, the loop is τ_f ë + ė + (k_true G) e = 0: a second-order system, stable for
//! any positive gain, with damping ratio ζ = 1/(2√(τ_f k_true G)) = √(8 k/k_true) for
//! τ_f = τ/32. With k exact (ζ = 2.8) the slow root is ≈ 1/τ (the error decays as e^{−t/τ},
//! no overshoot) and the fast one is the filter's; an overestimated k only slows the
//! approach in proportion; the loop is critically damped at k_true = 8k and k_true = 32k
//! still gives ζ = 0.5 (16 % overshoot). A fast filter costs nothing in speed, because the
//! integrator sets the pace, and buys this margin: the stiffness a wall sees is never known
//! well (a coarse mesh that resolves the contact by one node is several times stiffer
//! than Hertz). The estimate also leans high: for a Hertzian packing the tangent stiffness
//! grows with the load as F^{1/3}, and k is taken *at the target load*, so below the target
//! (the whole approach from first contact) the loop is more damped still. τ_f = τ/32 is
//! still hundreds of steps, enough to average the single-node arrests. Without the filter
//! the PI loop is ë + (k_true G) ė + (k_true G/τ_I) e = 0, damping ratio
//! ζ = √(k_true τ_I/(k τ))/2 = √(2 k_true/k): overdamped at k_true = k (ζ = 1.4), critical
//! at k_true = k/2, and more damped the more k is underestimated.
//!
//! The quasi-static assumption needs τ well above the period of the specimen's lowest
//! mode on that stiffness, T = 2π√(M/k) (M the mass of all grains), and above the time a
//! P wave needs to cross the specimen (L/c_p, c_p = √(E/ρ)); the default τ is the larger of
//! [`DEFAULT_PERIODS`]·T and [`DEFAULT_TRANSITS`]·L/c_p, so the loop is one decade slower
//! than the specimen's rigid mode (ωτ = 4π) and the same dimensionless loop results for any
//! material and size. That margin is for the hardest case, a lone grain between walls with
//! little damping and a stiffness underestimated 8× (a coarse mesh): with τ = T/2 or T it
//! overshoots by 17–18 % (the unit tests). A slow loop costs accuracy, though: in a
//! triaxial stage the lateral walls must follow the specimen's dilation at a speed v, and
//! until the integral has learnt v the proportional term lags by e/F* = v k τ/F*. At
//! failure the 172-sphere cell of `mufe validate thornton_walls` dilates at the axial rate,
//! and its lateral stress overshot the target by 29 % with τ = 2T against 7 % with τ = T/2
//! (the same peak ratio; docs/BENCHMARKS.md). A packing, damped by its many contacts and
//! its friction, runs stably at τ = T/2: the servo spec's `periods` sets it.
//!
//! `max_speed` caps |v| (default [`DEFAULT_SPEED_FRACTION`]·c_p: an impact at that speed
//! loads a grain by ~ρ c_p v = 10⁻⁴ E, far below yield and breakage).
//!
//! # Stiffness estimate (Hertz, at the target load)
//! One column of grains of radius R stands on each (2R)² of wall (exact for the (001)
//! face of an FCC packing), so a wall contact carries f = σ*(2R)² and has the Hertz
//! tangent stiffness k_c = (6 f R E'²)^{1/3} (sphere on a rigid plane, E' = E/(1−ν²) of the
//! stiffest material). A column spanning the specimen's extent L along n holds
//! m = max(1, L/(2R)) grains, i.e. two wall contacts and m − 1 grain contacts of stiffness
//! k_c/2 in series: k = (A/(2R)²)·k_c/(2m). Real packings are softer (inclined contacts,
//! more layers), which errs on the overdamped side. A coarse mesh that resolves the contact
//! by a single node is stiffer than Hertz; `stiffness` in the scene overrides the estimate.

use crate::scene::{normal_axis, Scene, ServoSpec, ShapeSpec, WallSpec};
use serde::{Deserialize, Serialize};

/// Filter time as a fraction of the loop time constant (τ_f = τ/32; see module docs).
pub const FILTER_FRACTION: f64 = 1.0 / 32.0;
/// Default τ in periods of the specimen's lowest mode on the estimated stiffness.
pub const DEFAULT_PERIODS: f64 = 2.0;
/// Lower bound of the default τ in P-wave transits across the specimen.
pub const DEFAULT_TRANSITS: f64 = 20.0;
/// Integral time of the PI law in loop time constants (τ_I = 8τ; see module docs).
pub const INTEGRAL_TIME_CONSTANTS: f64 = 8.0;
/// Default `max_speed` as a fraction of the largest P-wave speed of the scene.
pub const DEFAULT_SPEED_FRACTION: f64 = 1e-4;

/// The resolved settings of one servo wall (identical on every rank: computed from the
/// scene, not from a rank's grains).
#[derive(Debug, Clone, PartialEq)]
pub struct ServoControl {
    /// Target normal stress σ* (Pa) and the area it acts on (m²).
    pub target_stress: f64,
    pub area: f64,
    /// F* = σ* A (N).
    pub target_force: f64,
    /// Stiffness the wall is assumed to see at the target load (N/m).
    pub stiffness: f64,
    /// Closed-loop time constant τ (s).
    pub time_constant: f64,
    /// Low-pass filter time τ_f of the measured force (s).
    pub filter_time: f64,
    /// Largest wall speed (m/s).
    pub max_speed: f64,
    /// G = 1/(k τ) (m/s per N).
    pub gain: f64,
    /// τ_I = [`INTEGRAL_TIME_CONSTANTS`]·τ (s).
    pub integral_time: f64,
}

/// What a servo wall carries between steps (part of the wall's state in `State`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ServoState {
    /// Normal displacement s_n at t_n (m, positive into the grains).
    pub displacement: f64,
    /// s_{n−1} (m).
    pub previous: f64,
    /// Speed over the step t_n → t_{n+1} (m/s, positive into the grains).
    pub velocity: f64,
    /// Filtered normal force F̄ (N), global over ranks.
    pub filtered_force: f64,
    /// ∫ (F* − F̄) dt while the wall touches the grains (N·s): the integral action.
    #[serde(default)]
    pub error_integral: f64,
}

impl ServoState {
    /// Moves the wall to s_{n+1} at the current speed and sets the next step's speed
    /// (m/s, towards the grains).
    #[inline]
    pub fn move_on(&mut self, dt: f64, next_velocity: f64) {
        self.previous = self.displacement;
        self.displacement += dt * self.velocity;
        self.velocity = next_velocity;
    }

    /// Normal displacements at t_{n−1}, t_n and t_{n+1} (m).
    #[inline]
    pub fn displacements(&self, dt: f64) -> [f64; 3] {
        [
            self.previous,
            self.displacement,
            self.displacement + dt * self.velocity,
        ]
    }
}

impl ServoControl {
    /// Settings from a target stress, area, stiffness and time constant, with the filter
    /// and gain of the module docs.
    pub fn new(
        target_stress: f64,
        area: f64,
        stiffness: f64,
        time_constant: f64,
        max_speed: f64,
    ) -> Self {
        Self {
            target_stress,
            area,
            target_force: target_stress * area,
            stiffness,
            time_constant,
            filter_time: FILTER_FRACTION * time_constant,
            max_speed,
            gain: 1.0 / (stiffness * time_constant),
            integral_time: INTEGRAL_TIME_CONSTANTS * time_constant,
        }
    }

    /// After step n: filters the measured normal force F_n (N, summed over ranks), moves
    /// the wall to s_{n+1} and sets the speed of the next step.
    #[inline]
    pub fn advance(&self, s: &mut ServoState, force: f64, dt: f64) {
        self.advance_to(s, force, self.target_force, false, dt);
    }

    /// [`Self::advance`] towards `target_force` (N) instead of the fixed one (a stress
    /// held on an area that changes as the walls move), with the integral action when
    /// `tracking` (the specimen is being strained by other walls).
    #[inline]
    pub fn advance_to(
        &self,
        s: &mut ServoState,
        force: f64,
        target_force: f64,
        tracking: bool,
        dt: f64,
    ) {
        s.filtered_force += dt / (self.filter_time + dt) * (force - s.filtered_force);
        let error = target_force - s.filtered_force;
        let mut speed = self.gain * error;
        if tracking {
            speed += self.gain * s.error_integral / self.integral_time;
            // no wind-up while the wall approaches (nothing to push against) or is saturated
            if s.filtered_force > 0.0 && speed.abs() < self.max_speed {
                s.error_integral += dt * error;
            }
        }
        s.move_on(dt, speed.clamp(-self.max_speed, self.max_speed));
    }
}

/// Hertz estimate of the stiffness a wall sees at the target stress (N/m): see the module
/// docs. `radius` (m) of the grains, `e_prime` = E/(1−ν²) (Pa), `extent` (m) of the
/// specimen along the wall normal.
pub fn hertz_wall_stiffness(stress: f64, area: f64, radius: f64, e_prime: f64, extent: f64) -> f64 {
    let column = 4.0 * radius * radius;
    let contact_force = stress * column;
    let contact_stiffness = (6.0 * contact_force * radius * e_prime * e_prime).cbrt();
    let columns = (area / column).max(1.0);
    let grains_in_column = (extent / (2.0 * radius)).max(1.0);
    columns * contact_stiffness / (2.0 * grains_in_column)
}

/// τ (s): the larger of `periods` periods of mass `mass` (kg) on `stiffness` (N/m) and
/// [`DEFAULT_TRANSITS`] P-wave transits across `extent` (m) at `wave_speed` (m/s).
pub fn time_constant_of(
    periods: f64,
    mass: f64,
    stiffness: f64,
    extent: f64,
    wave_speed: f64,
) -> f64 {
    let period = 2.0 * std::f64::consts::PI * (mass / stiffness).sqrt();
    (periods * period).max(DEFAULT_TRANSITS * extent / wave_speed)
}

/// The area a servo acts on (m²): given, or the lattice span of packing `area_of` across
/// the wall normal (validated: the packing exists and the normal is an axis).
pub fn servo_area(scene: &Scene, wall: &WallSpec, spec: &ServoSpec) -> f64 {
    if let Some(a) = spec.area {
        return a;
    }
    let axis = normal_axis(wall.normal).unwrap_or(2);
    let geometry = scene.packing_geometry();
    let p = spec
        .area_of
        .as_ref()
        .and_then(|name| scene.packings.iter().position(|p| &p.name == name))
        .unwrap_or(0);
    let g = &geometry[p];
    (0..3)
        .filter(|&k| k != axis)
        .map(|k| g.span_max[k] - g.span_min[k])
        .product()
}

/// Resolves a wall's servo settings from the scene: area, the Hertz stiffness estimate
/// from the grains' mean radius, the stiffest material and the specimen's extent along the
/// normal, and the defaults of τ and `max_speed` (module docs).
pub fn servo_control(scene: &Scene, wall: &WallSpec, spec: &ServoSpec) -> ServoControl {
    let l = wall.normal.iter().map(|c| c * c).sum::<f64>().sqrt();
    let n = wall.normal.map(|c| c / l);
    let (mut mass, mut radius_sum, mut e_prime, mut wave_speed) = (0.0, 0.0, 0.0f64, 0.0f64);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for g in &scene.grains {
        let Some(m) = scene.materials.get(&g.material) else {
            continue;
        };
        // centre and bounding radius (extent), volume-equivalent radius (stiffness)
        let (centre, bounding, volume) = match &g.shape {
            ShapeSpec::Sphere(s) => (
                g.centre,
                s.radius,
                4.0 / 3.0 * std::f64::consts::PI * s.radius.powi(3),
            ),
            ShapeSpec::Block(b) => (
                [0, 1, 2].map(|k| g.centre[k] + 0.5 * b.size[k]),
                0.5 * b.size.iter().map(|s| s * s).sum::<f64>().sqrt(),
                b.size.iter().product(),
            ),
            ShapeSpec::Surface(s) => s.geometry.as_ref().map_or((g.centre, 0.0, 0.0), |x| {
                (g.centre, x.bounding_radius, x.descriptors.volume)
            }),
        };
        let along = centre[0] * n[0] + centre[1] * n[1] + centre[2] * n[2];
        lo = lo.min(along - bounding);
        hi = hi.max(along + bounding);
        mass += m.density * volume;
        radius_sum += (3.0 * volume / (4.0 * std::f64::consts::PI)).cbrt();
        e_prime = e_prime.max(m.youngs_modulus / (1.0 - m.poisson_ratio * m.poisson_ratio));
        wave_speed = wave_speed.max((m.youngs_modulus / m.density).sqrt());
    }
    let radius = radius_sum / scene.grains.len().max(1) as f64;
    let extent = if hi > lo { hi - lo } else { 2.0 * radius };
    let area = servo_area(scene, wall, spec);
    let stiffness = spec
        .stiffness
        .unwrap_or_else(|| hertz_wall_stiffness(spec.stress, area, radius, e_prime, extent));
    let time_constant = spec.time_constant.unwrap_or_else(|| {
        let periods = spec.periods.unwrap_or(DEFAULT_PERIODS);
        time_constant_of(periods, mass, stiffness, extent, wave_speed)
    });
    let max_speed = spec
        .max_speed
        .unwrap_or(DEFAULT_SPEED_FRACTION * wave_speed);
    ServoControl::new(spec.stress, area, stiffness, time_constant, max_speed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere (mass m, radius R) between a fixed wall at z = 0 and a servo wall above
    /// it, both Hertz contacts F = K δ^{3/2}, K = (4/3) E' √R, plus a light dashpot on the
    /// sphere (the packing's own damping). Returns the filtered force history (time, F̄).
    struct Plant {
        radius: f64,
        e_prime: f64,
        density: f64,
    }

    impl Plant {
        fn run(&self, stress: f64, stiffness_error: f64) -> (ServoControl, Vec<(f64, f64)>) {
            let r = self.radius;
            let mass = self.density * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
            let wave_speed = (self.e_prime / self.density).sqrt();
            let area = 4.0 * r * r;
            let k = hertz_wall_stiffness(stress, area, r, self.e_prime, 2.0 * r);
            let tau = time_constant_of(DEFAULT_PERIODS, mass, k, 2.0 * r, wave_speed);
            // the controller believes k; the plant is what it is
            let control = ServoControl::new(
                stress,
                area,
                k / stiffness_error,
                tau,
                DEFAULT_SPEED_FRACTION * wave_speed,
            );
            let hertz = 4.0 / 3.0 * self.e_prime * r.sqrt();
            let force = |overlap: f64| hertz * overlap.max(0.0).powf(1.5);
            // both walls touching the sphere at t = 0 (a gap is closed at G F*; see docs)
            let top0 = 2.0 * r;
            let (mut z, mut vz) = (r, 0.0);
            let period = 2.0 * std::f64::consts::PI * (mass / k).sqrt();
            let dt = period / 400.0;
            let damping = 0.1 * (k * mass).sqrt();
            let mut s = ServoState::default();
            let mut out = Vec::new();
            let steps = (15.0 * tau / dt) as usize;
            for n in 0..steps {
                let [_, now, _] = s.displacements(dt);
                let top = top0 - now;
                let f_wall = force(z + r - top);
                let f_floor = force(r - z);
                vz += dt * (f_floor - f_wall - damping * vz) / mass;
                z += dt * vz;
                control.advance(&mut s, f_wall, dt);
                out.push((n as f64 * dt, s.filtered_force));
            }
            (control, out)
        }
    }

    fn check(plant: &Plant, stiffness_error: f64, overshoot_bound: f64) {
        let (c, h) = plant.run(5.0e4, stiffness_error);
        let t_end = h.last().unwrap().0;
        let peak = h.iter().map(|p| p.1).fold(0.0, f64::max);
        let tail: Vec<f64> = h
            .iter()
            .filter(|p| p.0 > t_end - 3.0 * c.time_constant)
            .map(|p| (p.1 - c.target_force).abs() / c.target_force)
            .collect();
        let worst = tail.iter().cloned().fold(0.0, f64::max);
        assert!(
            worst < 0.01,
            "held within {worst:.2e} of the target over the last 3τ (τ = {:.3e} s)",
            c.time_constant
        );
        assert!(
            peak <= (1.0 + overshoot_bound) * c.target_force,
            "overshoot {:.3} > {overshoot_bound}",
            peak / c.target_force - 1.0
        );
    }

    const GLASS: Plant = Plant {
        radius: 1.1e-3,
        e_prime: 63e9 / (1.0 - 0.22 * 0.22),
        density: 2500.0,
    };
    const SOFT_ROCK: Plant = Plant {
        radius: 2.0e-2,
        e_prime: 0.5e9 / (1.0 - 0.3 * 0.3),
        density: 1800.0,
    };

    #[test]
    fn converges_without_overshoot_for_glass_and_soft_rock() {
        check(&GLASS, 1.0, 0.005);
        check(&SOFT_ROCK, 1.0, 0.005);
    }

    #[test]
    fn tolerates_a_stiffness_underestimated_many_times() {
        // The packing 8× stiffer than estimated: critically damped quasi-statically; what
        // overshoot remains is the sphere's barely damped bounce, excited by the wall's
        // start at full speed. 20× (a contact resolved by one node): ζ ≈ 0.63.
        check(&GLASS, 8.0, 0.10);
        check(&SOFT_ROCK, 8.0, 0.10);
        check(&GLASS, 20.0, 0.30);
        check(&SOFT_ROCK, 20.0, 0.30);
    }

    #[test]
    fn integral_action_follows_a_steadily_yielding_specimen() {
        // F = k (s − v_y t): the specimen gives way at v_y; the wall must keep up
        let (k, tau, target) = (1.0e6, 1.0e-4, 0.5);
        let control = ServoControl::new(target / 1.0e-5, 1.0e-5, k, tau, 1.0);
        let v_y = 0.2 * target / (k * tau); // P law alone: 20 % error
        let dt = tau / 2000.0;
        let run = |tracking: bool| {
            let mut s = ServoState {
                displacement: target / k,
                previous: target / k,
                filtered_force: target,
                ..Default::default()
            };
            let steps = (6.0 * control.integral_time / dt) as usize;
            for n in 0..steps {
                let force = k * (s.displacement - v_y * n as f64 * dt);
                control.advance_to(&mut s, force, target, tracking, dt);
            }
            (s.filtered_force - target) / target
        };
        let (p_only, pi) = (run(false), run(true));
        assert!((p_only + 0.2).abs() < 0.01, "P law: steady error {p_only}");
        assert!(
            pi.abs() < 0.01 * p_only.abs(),
            "PI law: error {pi} after 6 τ_I"
        );
    }

    #[test]
    fn speed_is_capped_and_displacements_follow_the_speed() {
        let c = ServoControl::new(1.0e5, 1.0e-4, 1.0e3, 1.0e-3, 0.01);
        let mut s = ServoState::default();
        c.advance(&mut s, 0.0, 1e-6);
        // G F* = 10/(1e3·1e-3) = 10 m/s → capped
        assert_eq!(s.velocity, 0.01);
        let d = s.displacements(1e-6);
        assert_eq!(d[2] - d[1], 1e-8);
        c.advance(&mut s, 0.0, 1e-6);
        assert_eq!(s.previous, 0.0);
        assert_eq!(s.displacement, 1e-8);
    }
}
