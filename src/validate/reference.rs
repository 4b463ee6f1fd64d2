//! Analytic reference solutions (THEORY.md), for any material: every number a validation
//! compares against is computed here from its formula.

use crate::material::ElasticParameters;

/// Hertz normal contact of a sphere (radius R) against a rigid flat, or of two identical
/// spheres: F = (4/3) E* √R* δ^{3/2}, a = √(R* δ).
#[derive(Debug, Clone, Copy)]
pub struct Hertz {
    /// Effective modulus E* (Pa).
    pub e_star: f64,
    /// Effective radius R* (m).
    pub r_star: f64,
}

impl Hertz {
    /// Sphere on a rigid flat: E* = E/(1−ν²), R* = R.
    pub fn sphere_on_flat(m: &ElasticParameters, radius: f64) -> Self {
        Self {
            e_star: m.plane_strain_modulus(),
            r_star: radius,
        }
    }
    /// Two identical spheres, δ = total approach: E* = E/(2(1−ν²)), R* = R/2.
    pub fn identical_spheres(m: &ElasticParameters, radius: f64) -> Self {
        Self {
            e_star: 0.5 * m.plane_strain_modulus(),
            r_star: 0.5 * radius,
        }
    }
    /// F(δ) (N).
    pub fn force(&self, delta: f64) -> f64 {
        4.0 / 3.0 * self.e_star * self.r_star.sqrt() * delta.max(0.0).powf(1.5)
    }
    /// δ(F) (m).
    pub fn approach(&self, force: f64) -> f64 {
        (3.0 * force / (4.0 * self.e_star * self.r_star.sqrt())).powf(2.0 / 3.0)
    }
    /// Contact radius a = (3FR*/(4E*))^{1/3} (m).
    pub fn contact_radius(&self, force: f64) -> f64 {
        (3.0 * force * self.r_star / (4.0 * self.e_star)).cbrt()
    }
    /// Peak pressure p0 = 3F/(2πa²) (Pa).
    pub fn peak_pressure(&self, force: f64) -> f64 {
        let a = self.contact_radius(force);
        3.0 * force / (2.0 * std::f64::consts::PI * a * a)
    }
}

/// The converged finite-sphere reference (THEORY.md §1): F_ref(δ) for a sphere between two
/// rigid frictionless plates, tabulated for the paper's material and R = 1.1 mm, rescaled
/// to other materials/radii by the exact similarity of linear elasticity: F/(E*R²) is a
/// function of δ/R only.
#[derive(Debug, Clone)]
pub struct FiniteSphereReference {
    /// (δ/R, F/(E* R²)) pairs, ascending.
    points: Vec<(f64, f64)>,
}

/// The table as shipped (converged axisymmetric FE; see the CSV header).
pub const FINITE_SPHERE_CSV: &str =
    include_str!("../../jobs/validation/hertz_finite_sphere_reference.csv");

impl FiniteSphereReference {
    /// Parses the CSV (R = 1.1 mm, E = 63 GPa, ν = 0.22 in the table).
    pub fn load() -> Self {
        let table = ElasticParameters::paper_glass();
        let (r, e_star) = (1.1e-3, table.plane_strain_modulus());
        let mut points = Vec::new();
        for line in FINITE_SPHERE_CSV.lines() {
            let cols: Vec<&str> = line.split(',').collect();
            if let (Some(d), Some(f)) = (
                cols.first().and_then(|s| s.trim().parse::<f64>().ok()),
                cols.get(1).and_then(|s| s.trim().parse::<f64>().ok()),
            ) {
                points.push((d * 1e-6 / r, f / (e_star * r * r)));
            }
        }
        Self { points }
    }

    /// F_ref(δ) (N) for a sphere of `radius` and `material`, log–log interpolated; `None`
    /// outside the table.
    pub fn force(&self, material: &ElasticParameters, radius: f64, delta: f64) -> Option<f64> {
        let x = delta / radius;
        let p = &self.points;
        if p.is_empty() || x < p[0].0 || x > p[p.len() - 1].0 {
            return None;
        }
        let k = p.partition_point(|q| q.0 <= x).min(p.len() - 1).max(1);
        let (x0, y0) = p[k - 1];
        let (x1, y1) = p[k];
        let s = (x.ln() - x0.ln()) / (x1.ln() - x0.ln());
        let y = (y0.ln() + s * (y1.ln() - y0.ln())).exp();
        Some(y * material.plane_strain_modulus() * radius * radius)
    }
}

/// Mindlin–Deresiewicz tangential loading of two identical spheres at constant N.
#[derive(Debug, Clone, Copy)]
pub struct Mindlin {
    pub mu: f64,
    pub normal_force: f64,
    /// δt,max = 3μN(2−ν)/(8Ga) (m), total relative tangential displacement at full slip.
    pub slip_displacement: f64,
}

impl Mindlin {
    pub fn identical_spheres(
        m: &ElasticParameters,
        radius: f64,
        mu: f64,
        normal_force: f64,
    ) -> Self {
        let a = Hertz::identical_spheres(m, radius).contact_radius(normal_force);
        let g = m.shear_modulus();
        let nu = m.poisson_ratio;
        Self {
            mu,
            normal_force,
            slip_displacement: 3.0 * mu * normal_force * (2.0 - nu) / (8.0 * g * a),
        }
    }
    /// Q(δt) on monotonic loading from zero: μN[1 − (1 − δt/δt,max)^{3/2}].
    pub fn loading(&self, dt: f64) -> f64 {
        let x = (dt.abs() / self.slip_displacement).min(1.0);
        dt.signum() * self.mu * self.normal_force * (1.0 - (1.0 - x).powf(1.5))
    }
    /// Masing unloading from a reversal at (δ*, Q*): Q = Q* − 2 Q_load((δ* − δ)/2).
    pub fn unloading(&self, reversal_dt: f64, reversal_q: f64, dt: f64) -> f64 {
        reversal_q - 2.0 * self.loading(0.5 * (reversal_dt - dt))
    }
}

/// Complete elliptic integrals K(k), E(k) of modulus k (0 ≤ k < 1) by the AGM.
pub fn elliptic_k_e(k: f64) -> (f64, f64) {
    let mut a = 1.0;
    let mut b = (1.0 - k * k).sqrt();
    let mut c = k;
    let mut sum = 0.5 * c * c;
    let mut pow = 0.5;
    for _ in 0..60 {
        let an = 0.5 * (a + b);
        let bn = (a * b).sqrt();
        c = 0.5 * (a - b);
        pow *= 2.0;
        sum += pow * c * c;
        a = an;
        b = bn;
        if c.abs() < 1e-16 {
            break;
        }
    }
    let kk = std::f64::consts::PI / (2.0 * a);
    (kk, kk * (1.0 - sum))
}

/// Lubkin's exact torsion of a Hertzian contact under constant N, parametrised by the stick
/// radius c: twist of one body β(c) and moment M(c).
#[derive(Debug, Clone, Copy)]
pub struct Lubkin {
    pub mu: f64,
    pub normal_force: f64,
    /// Contact radius a (m).
    pub a: f64,
    pub shear_modulus: f64,
}

impl Lubkin {
    pub fn identical_spheres(
        m: &ElasticParameters,
        radius: f64,
        mu: f64,
        normal_force: f64,
    ) -> Self {
        let a = Hertz::identical_spheres(m, radius).contact_radius(normal_force);
        Self {
            mu,
            normal_force,
            a,
            shear_modulus: m.shear_modulus(),
        }
    }
    /// Full-slip moment M_max = 3πμNa/16 (N·m).
    pub fn full_slip_moment(&self) -> f64 {
        3.0 * std::f64::consts::PI * self.mu * self.normal_force * self.a / 16.0
    }
    /// (β per body (rad), M (N·m)) at stick radius c.
    pub fn point(&self, c: f64) -> (f64, f64) {
        let a = self.a;
        let k = (1.0 - (c / a).powi(2)).max(0.0).sqrt();
        let (kk, ee) = elliptic_k_e(k);
        let beta = 3.0 * self.mu * self.normal_force
            / (4.0 * std::f64::consts::PI * self.shear_modulus * a * a)
            * (kk - ee);
        let p0 = 3.0 * self.normal_force / (2.0 * std::f64::consts::PI * a * a);
        // M = (8μp0/3) ∫_c^a E(√(1 − t²/a²)) t² dt, Simpson's rule
        let n = 400;
        let h = (a - c) / n as f64;
        let f = |t: f64| elliptic_k_e((1.0 - (t / a).powi(2)).max(0.0).sqrt()).1 * t * t;
        let mut s = f(c) + f(a);
        for i in 1..n {
            s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(c + i as f64 * h);
        }
        let integral = s * h / 3.0;
        (beta, 8.0 * self.mu * p0 / 3.0 * integral)
    }
    /// M at a relative twist of two identical spheres 2β (rad), by bisection on c.
    pub fn moment_at_relative_twist(&self, twist: f64) -> f64 {
        let beta = 0.5 * twist.abs();
        if beta <= 0.0 {
            return 0.0;
        }
        let (mut lo, mut hi) = (1e-9 * self.a, self.a);
        if self.point(lo).0 < beta {
            return twist.signum() * self.point(lo).1;
        }
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if self.point(mid).0 > beta {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        twist.signum() * self.point(0.5 * (lo + hi)).1
    }
}

/// Rolling about a fixed centre under constant N (THEORY.md §4): δt = Rθ at the contact, so
/// M(θ) = R μN[1 − (1 − Rθ/δt,max)^{3/2}], M_max = μNR.
#[derive(Debug, Clone, Copy)]
pub struct Rolling {
    pub radius: f64,
    pub mindlin: Mindlin,
}

impl Rolling {
    pub fn moment(&self, theta: f64) -> f64 {
        self.radius * self.mindlin.loading(self.radius * theta)
    }
    pub fn max_moment(&self) -> f64 {
        self.mindlin.mu * self.mindlin.normal_force * self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hertz_matches_theory_table_for_paper_material() {
        // THEORY.md §1 table: the formulas, evaluated, agree with the printed values.
        let m = ElasticParameters::paper_glass();
        let pair = Hertz::identical_spheres(&m, 1.1e-3);
        let flat = Hertz::sphere_on_flat(&m, 1.1e-3);
        assert!((pair.force(1e-6) - 1.035).abs() < 0.002);
        assert!((flat.force(10e-6) - 92.58).abs() < 0.05);
        assert!((pair.contact_radius(pair.force(5e-6)) - 52.44e-6).abs() < 0.02e-6);
    }

    #[test]
    fn finite_sphere_reference_reproduces_its_table_and_exceeds_hertz() {
        let m = ElasticParameters::paper_glass();
        let r = FiniteSphereReference::load();
        assert!((r.force(&m, 1.1e-3, 5e-6).unwrap() - 33.7846).abs() < 1e-6 * 33.8);
        let flat = Hertz::sphere_on_flat(&m, 1.1e-3);
        let ratio = r.force(&m, 1.1e-3, 2e-6).unwrap() / flat.force(2e-6);
        assert!(ratio > 1.0 && ratio < 1.03);
        assert!(r.force(&m, 1.1e-3, 1e-3).is_none());
    }

    #[test]
    fn elliptic_integrals_known_values() {
        let (k, e) = elliptic_k_e(0.0);
        assert!(
            (k - std::f64::consts::FRAC_PI_2).abs() < 1e-14
                && (e - std::f64::consts::FRAC_PI_2).abs() < 1e-14
        );
        // K(1/√2) = Γ(1/4)²/(4√π) = 1.854074677301372
        let (k, e) = elliptic_k_e(0.5f64.sqrt());
        assert!((k - 1.854_074_677_301_372).abs() < 1e-12);
        assert!((e - 1.350_643_881_047_675).abs() < 1e-12);
    }

    #[test]
    fn lubkin_reproduces_theory_table() {
        // THEORY.md §3: c/a = 0.6 → M/(μNa) = 0.481, G a² β/(μN) = 0.1716
        let m = ElasticParameters::paper_glass();
        let l = Lubkin::identical_spheres(&m, 1.1e-3, 0.22, 70.0);
        let (beta, moment) = l.point(0.6 * l.a);
        let mun = l.mu * l.normal_force;
        assert!(
            (moment / (mun * l.a) - 0.481).abs() < 0.002,
            "{}",
            moment / (mun * l.a)
        );
        assert!((l.shear_modulus * l.a * l.a * beta / mun - 0.1716).abs() < 0.001);
        // M → M_max as c → 0, and M_max(70 N) = 8.668e-4 N·m
        assert!((l.full_slip_moment() - 8.668e-4).abs() < 0.002e-4);
        assert!((l.point(1e-6 * l.a).1 / l.full_slip_moment() - 1.0).abs() < 1e-3);
        // initial stiffness per body 16 G a³/3
        let (b, mo) = l.point(0.999 * l.a);
        let k = mo / b;
        assert!(
            (k / (16.0 * l.shear_modulus * l.a.powi(3) / 3.0) - 1.0).abs() < 0.02,
            "{k}"
        );
    }

    #[test]
    fn mindlin_matches_theory_table() {
        let m = ElasticParameters::paper_glass();
        let md = Mindlin::identical_spheres(&m, 1.1e-3, 0.22, 5.0);
        assert!((md.slip_displacement - 0.7173e-6).abs() < 0.001e-6);
        assert!((md.loading(0.5 * md.slip_displacement) - 0.711).abs() < 0.001);
        // Masing: unloading from full slip by 2δt,max reaches −μN
        let q = md.unloading(md.slip_displacement, md.mu * 5.0, -md.slip_displacement);
        assert!((q + md.mu * 5.0).abs() < 1e-12);
    }
}
