//! The dimensionless parameters of the generated validation scenes, one struct per case
//! family, with the paper's values as defaults.

use super::{paper, Units};
use crate::error::InputError;

/// Hertz: one sphere squeezed between two rigid frictionless plates.
#[derive(Debug, Clone, PartialEq)]
pub struct HertzParams {
    /// Plate speed after the ramp (c_p).
    pub v_plate: f64,
    /// Raised-cosine ramp of the plate speed (R/c_p; 0: constant speed from t = 0).
    pub ramp: f64,
    /// Exponential drive when > 0 (then `v_plate` and `ramp` are unused): each plate's
    /// travel from first touch is δ(t) = δ0 (e^{t/τ} − 1), so its speed (δ + δ0)/τ and
    /// acceleration (δ + δ0)/τ² grow with δ and the relative inertia of the contact zone,
    /// ∝ (v²/δ + a)/δ, is uniform over the load range (τ in R/c_p).
    pub tau: f64,
    /// δ0 of the exponential drive (R): the speed at first touch is δ0/τ.
    pub delta0: f64,
    /// Initial gap between each plate and its pole (R).
    pub gap: f64,
    /// Plate travel covered by the duration, as the Hertz contact radius √(δR) it gives (R).
    pub a_end: f64,
    /// Mass scaling of the fine contact elements (R/c_p).
    pub target_dt: f64,
    /// Global surface seeding (R).
    pub seeding: f64,
    /// Seeding of the pole patches as written (R); `mufe validate` sets it from MR.
    pub refine_seeding: f64,
    /// Radius of the fine zone around each pole, chord distance (R).
    pub refine_radius: f64,
    /// Growth of the edge length beyond the fine zone (–).
    pub growth: f64,
    /// Deformation damping (c_p/R).
    pub damping: f64,
    /// History sampling interval (R/c_p).
    pub history_interval: f64,
}

impl Default for HertzParams {
    /// On the paper's glass: an exponential drive δ = δ0 (e^{t/τ} − 1) with δ0 = 0.03 µm
    /// and τ such that the travel to 7.2 µm (F_ref ≈ 55 N) takes 15 µs, target_dt 3 ns,
    /// seeding 150 µm, patches of radius 0.02 R = 22 µm (1.2 × the contact radius at the
    /// window's low end) with growth 0.12, history every 25 ns. The original study's
    /// raised-cosine ramp (0.6 m/s after 6 µs) stays available as `tau = 0` with
    /// `v_plate`, `ramp` (docs/BENCHMARKS.md, "Hertz bias").
    fn default() -> Self {
        let u = Units::paper();
        let (delta0, delta_end, duration): (f64, f64, f64) = (3.0e-8, 7.2e-6, 15.0e-6);
        Self {
            v_plate: 0.6 / u.speed,
            ramp: 6.0e-6 / u.time,
            tau: duration / (1.0 + delta_end / delta0).ln() / u.time,
            delta0: delta0 / u.length,
            gap: 0.0,
            a_end: (delta_end / u.length).sqrt(),
            target_dt: 3.0e-9 / u.time,
            seeding: 1.5e-4 / u.length,
            refine_seeding: 1.0e-5 / u.length,
            refine_radius: 0.02,
            growth: 0.12,
            damping: 0.0,
            history_interval: 2.5e-8 / u.time,
        }
    }
}

/// `hertz_ellipsoid` (an ellipsoid between plates, `validate::hertz_ellipsoid`): generator
/// parameters (`--param hertz_ellipsoid.KEY=VALUE`), lengths in R_e, times in
/// R_e/c_p: the same dimensionless drive as the sphere case's (`hertz`).
#[derive(Debug, Clone, PartialEq)]
pub struct HertzEllipsoidParams {
    /// Exponential drive δ = δ0 (e^{t/τ} − 1) of each plate (R_e/c_p, R_e).
    pub tau: f64,
    pub delta0: f64,
    /// Mass scaling of the fine tip elements (R_e/c_p).
    pub target_dt: f64,
    /// Facet edge away from the tips (R_e).
    pub seeding: f64,
    /// Radius of the fine tip patch (R_e) and growth of the edge beyond it (–).
    pub tip_radius: f64,
    pub growth: f64,
    /// History sampling interval (R_e/c_p).
    pub history_interval: f64,
}

impl Default for HertzEllipsoidParams {
    /// The `hertz` case's τ, δ0 and target_dt in units of R_e instead of R; a tip patch of
    /// 1.2 × the major semi-axis at the window's low end (as the sphere's pole patch),
    /// growth 0.12, bulk facets of R_e/7.
    fn default() -> Self {
        let sphere = HertzParams::default();
        Self {
            tau: sphere.tau,
            delta0: sphere.delta0,
            target_dt: sphere.target_dt,
            seeding: 0.14,
            tip_radius: 0.014,
            growth: 0.12,
            history_interval: sphere.history_interval,
        }
    }
}

impl HertzEllipsoidParams {
    fn fields(&mut self) -> Vec<(&'static str, &mut f64)> {
        vec![
            ("tau", &mut self.tau),
            ("delta0", &mut self.delta0),
            ("target_dt", &mut self.target_dt),
            ("seeding", &mut self.seeding),
            ("tip_radius", &mut self.tip_radius),
            ("growth", &mut self.growth),
            ("history_interval", &mut self.history_interval),
        ]
    }
}

/// Two identical spheres touching at the origin (Mindlin, torsion, rolling).
#[derive(Debug, Clone, PartialEq)]
pub struct TwoSphereParams {
    /// Nominal normal load, as its Hertz contact radius (R).
    pub a_over_r: f64,
    /// Fraction of the Hertz approach at that load the drive moves down: the held parts at
    /// ±clamp·R make the pair stiffer than two half-spaces, and this brings the measured N
    /// close to the nominal one.
    pub approach_scale: f64,
    /// Normal approach speed (c_p), its ramps (R/c_p) and the rest after it (R/c_p).
    pub vn: f64,
    pub n_ramp: f64,
    pub settle: f64,
    /// Mindlin: tangential speed (δt,max per R/c_p, so the legs take the same time for any
    /// μ and material), amplitude (δt,max) and reversals (1: unload to −amplitude; 2: then
    /// reload to +amplitude).
    pub vt: f64,
    pub amplitude: f64,
    pub reversals: f64,
    /// Torsion: final G a² β/(μN) per sphere.
    pub twist_param: f64,
    /// Torsion and rolling: constant-speed time of the case motion (R/c_p).
    pub cruise: f64,
    /// Raised-cosine ramps of the case motion (R/c_p).
    pub t_ramp: f64,
    /// Time after the case motion (R/c_p).
    pub tail: f64,
    /// Mass scaling of the fine contact elements (R/c_p).
    pub target_dt: f64,
    /// Deformation damping (c_p/R).
    pub damping: f64,
    /// Global seeding (R), patch seeding as written (R), patch radius (R), growth (–).
    pub seeding: f64,
    pub refine_seeding: f64,
    pub refine_radius: f64,
    pub growth: f64,
    /// History sampling interval (R/c_p).
    pub history_interval: f64,
    /// Held/driven parts: beyond the planes at ∓clamp·R from the contact (1 = the far
    /// hemispheres). See docs/BENCHMARKS.md (Validation) for its effect.
    pub clamp: f64,
}

impl TwoSphereParams {
    /// Parameters shared by the three cases on the paper's glass: approach at 1 m/s (5 N)
    /// or 4 m/s (70 N) with 2 µs ramps, 2 µs rest, target_dt 2 ns, damping 2×10⁶ 1/s,
    /// seeding 275 µm, history every 20 ns, clamp R/2, 0.2 µs tail.
    fn paper_common(force: f64, vn: f64, refine_radius: f64, growth: f64) -> Self {
        let u = Units::paper();
        Self {
            a_over_r: u.a_over_r(force),
            approach_scale: 0.92,
            vn: vn / u.speed,
            n_ramp: 2.0e-6 / u.time,
            settle: 2.0e-6 / u.time,
            vt: 0.0,
            amplitude: 0.0,
            reversals: 0.0,
            twist_param: 0.0,
            cruise: 0.0,
            t_ramp: 2.0e-6 / u.time,
            tail: 0.2e-6 / u.time,
            target_dt: 2.0e-9 / u.time,
            damping: 2.0e6 * u.time,
            seeding: 2.75e-4 / u.length,
            refine_seeding: 1.0e-5 / u.length,
            refine_radius: refine_radius / u.length,
            growth,
            history_interval: 2.0e-8 / u.time,
            clamp: 0.5,
        }
    }

    /// Mindlin on the paper's glass: N = 5 N, 0.4 m/s tangential with 1.5 µs ramps to
    /// ±1.2 δt,max and back (two reversals), patch 20 µm with growth 0.15.
    pub fn mindlin() -> Self {
        let u = Units::paper();
        let mut p = Self::paper_common(5.0, 1.0, 2.0e-5, 0.15);
        let dtmax = u.slip_displacement(paper::FRICTION, p.a_over_r);
        p.vt = 0.4 / (dtmax / u.time);
        p.t_ramp = 1.5e-6 / u.time;
        p.amplitude = 1.2;
        p.reversals = 2.0;
        p
    }

    /// The full cycle of `mindlin_cyclic`: as [`Self::mindlin`], to ±0.8 δt,max (partial
    /// slip throughout, Q*/μN = 0.91) and back twice, at 3/4 of its tangential speed (the
    /// shorter legs still fit their ramps).
    pub fn mindlin_cyclic() -> Self {
        let mut p = Self::mindlin();
        p.amplitude = 0.8;
        p.vt *= 0.75;
        p
    }

    /// Torsion on the paper's glass: N = 70 N, relative twist to G a² β/(μN) = 0.6 (c/a ≈
    /// 0.1) in 9 µs, patch 110 µm with growth 0.3.
    pub fn torsion() -> Self {
        let u = Units::paper();
        let mut p = Self::paper_common(70.0, 4.0, 1.1e-4, 0.3);
        p.twist_param = 0.6;
        p.cruise = 5.0e-6 / u.time;
        p
    }

    /// Rolling on the paper's glass: N = 70 N, rotation to 1.5 θ_slip in 9 µs, patch
    /// 110 µm with growth 0.3.
    pub fn rolling() -> Self {
        let u = Units::paper();
        let mut p = Self::paper_common(70.0, 4.0, 1.1e-4, 0.3);
        p.amplitude = 1.5;
        p.cruise = 5.0e-6 / u.time;
        p
    }
}

/// The generator parameters of all four cases (`mufe validate --param CASE.KEY=VALUE`).
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    pub hertz: HertzParams,
    pub mindlin: TwoSphereParams,
    pub mindlin_cyclic: TwoSphereParams,
    pub torsion: TwoSphereParams,
    pub rolling: TwoSphereParams,
    pub thornton_walls: crate::validate::thornton_scene::ThorntonParams,
    pub thornton: crate::validate::thornton_scene::ThorntonParams,
    pub hertz_ellipsoid: HertzEllipsoidParams,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            hertz: HertzParams::default(),
            mindlin: TwoSphereParams::mindlin(),
            mindlin_cyclic: TwoSphereParams::mindlin_cyclic(),
            torsion: TwoSphereParams::torsion(),
            rolling: TwoSphereParams::rolling(),
            thornton_walls: Default::default(),
            thornton: crate::validate::thornton_scene::ThorntonParams::periodic(),
            hertz_ellipsoid: Default::default(),
        }
    }
}

impl HertzParams {
    fn fields(&mut self) -> Vec<(&'static str, &mut f64)> {
        vec![
            ("v_plate", &mut self.v_plate),
            ("ramp", &mut self.ramp),
            ("tau", &mut self.tau),
            ("delta0", &mut self.delta0),
            ("gap", &mut self.gap),
            ("a_end", &mut self.a_end),
            ("target_dt", &mut self.target_dt),
            ("seeding", &mut self.seeding),
            ("refine_seeding", &mut self.refine_seeding),
            ("refine_radius", &mut self.refine_radius),
            ("growth", &mut self.growth),
            ("damping", &mut self.damping),
            ("history_interval", &mut self.history_interval),
        ]
    }
}

impl TwoSphereParams {
    fn fields(&mut self) -> Vec<(&'static str, &mut f64)> {
        vec![
            ("a_over_r", &mut self.a_over_r),
            ("approach_scale", &mut self.approach_scale),
            ("vn", &mut self.vn),
            ("n_ramp", &mut self.n_ramp),
            ("settle", &mut self.settle),
            ("vt", &mut self.vt),
            ("amplitude", &mut self.amplitude),
            ("reversals", &mut self.reversals),
            ("twist_param", &mut self.twist_param),
            ("cruise", &mut self.cruise),
            ("t_ramp", &mut self.t_ramp),
            ("tail", &mut self.tail),
            ("target_dt", &mut self.target_dt),
            ("damping", &mut self.damping),
            ("seeding", &mut self.seeding),
            ("refine_seeding", &mut self.refine_seeding),
            ("refine_radius", &mut self.refine_radius),
            ("growth", &mut self.growth),
            ("history_interval", &mut self.history_interval),
            ("clamp", &mut self.clamp),
        ]
    }
}

impl Params {
    /// Applies `CASE.KEY=VALUE` (dimensionless, in the units documented on the field).
    pub fn set(&mut self, assignment: &str) -> Result<(), InputError> {
        let item = format!("--param {}", crate::error::echo(assignment));
        let bad = |m: String| InputError::new("<command line>", &item, m);
        let (key, value) = assignment
            .split_once('=')
            .ok_or_else(|| bad("expected CASE.KEY=VALUE".into()))?;
        let (case, field) = key
            .trim()
            .split_once('.')
            .ok_or_else(|| bad("expected CASE.KEY=VALUE".into()))?;
        let value: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| bad(format!("'{}' is not a finite number", value.trim())))?;
        let mut fields = match case {
            "hertz" => self.hertz.fields(),
            "mindlin" => self.mindlin.fields(),
            "mindlin_cyclic" => self.mindlin_cyclic.fields(),
            "torsion" => self.torsion.fields(),
            "rolling" => self.rolling.fields(),
            "thornton_walls" => self.thornton_walls.fields(),
            "thornton" => self.thornton.fields(),
            "hertz_ellipsoid" => self.hertz_ellipsoid.fields(),
            other => {
                return Err(bad(format!(
                    "unknown case '{other}' (known: {})",
                    crate::validate::CASE_NAMES.join(", ")
                )))
            }
        };
        let names: Vec<&str> = fields.iter().map(|f| f.0).collect();
        let names = names.join(", ");
        let slot = fields
            .iter_mut()
            .find(|f| f.0 == field.trim())
            .ok_or_else(|| bad(format!("unknown parameter (known: {names})")))?;
        *slot.1 = value;
        Ok(())
    }
}
