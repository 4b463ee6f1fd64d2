//! Analytic reference solutions (docs/THEORY.md), for any material: every number a validation
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

/// The converged finite-sphere reference (docs/THEORY.md §1): a sphere between two rigid
/// frictionless plates, tabulated dimensionlessly (F/(E*R²) against δ/R, E* = E/(1−ν²),
/// exact similarity of linear elasticity) for a set of Poisson ratios in
/// `jobs/validation/hertz_finite_sphere_table.csv`. Between two tabulated ν the curve is
/// interpolated linearly in ν; along each ν it is interpolated log–log in δ/R.
#[derive(Debug, Clone)]
pub struct FiniteSphereTable {
    /// Per ν (ascending): the curve's rows, ascending in δ/R.
    curves: Vec<(f64, Vec<Row>)>,
}

/// One tabulated point: (ln δ/R, ln F/(E*R²), a/R).
type Row = (f64, f64, f64);

/// Path of the table, as named in error messages.
pub const FINITE_SPHERE_TABLE_PATH: &str = "jobs/validation/hertz_finite_sphere_table.csv";

/// The table as shipped (converged axisymmetric FE; see its comment lines).
pub const FINITE_SPHERE_TABLE_CSV: &str =
    include_str!("../../jobs/validation/hertz_finite_sphere_table.csv");

/// The original single-ν table (R = 1.1 mm, E = 63 GPa, ν = 0.22, dimensional), kept as
/// the check of the ν = 0.22 rows of [`FINITE_SPHERE_TABLE_CSV`].
pub const FINITE_SPHERE_CSV: &str =
    include_str!("../../jobs/validation/hertz_finite_sphere_reference.csv");

impl FiniteSphereTable {
    /// Parses `#` comment lines, the header `nu,delta_over_R,F_over_EstarR2,a_over_R`, then
    /// rows. Errors name the line.
    pub fn parse(text: &str) -> std::result::Result<Self, String> {
        let mut curves: Vec<(f64, Vec<Row>)> = Vec::new();
        let mut header = false;
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            if !header {
                if line.replace(' ', "") != "nu,delta_over_R,F_over_EstarR2,a_over_R" {
                    return Err(format!(
                        "line {}: expected the header nu,delta_over_R,F_over_EstarR2,a_over_R",
                        i + 1
                    ));
                }
                header = true;
                continue;
            }
            let cols: std::result::Result<Vec<f64>, _> =
                line.split(',').map(|c| c.trim().parse::<f64>()).collect();
            let cols = match cols {
                Ok(c) if c.len() == 4 && c.iter().all(|v| v.is_finite()) => c,
                _ => return Err(format!("line {}: expected four finite numbers", i + 1)),
            };
            let (nu, d, f, a) = (cols[0], cols[1], cols[2], cols[3]);
            if !(d > 0.0 && f > 0.0) {
                return Err(format!("line {}: δ/R and F/(E*R²) must be > 0", i + 1));
            }
            match curves.iter_mut().find(|c| c.0 == nu) {
                Some(c) => c.1.push((d.ln(), f.ln(), a)),
                None => curves.push((nu, vec![(d.ln(), f.ln(), a)])),
            }
        }
        if curves.is_empty() {
            return Err("no rows".into());
        }
        curves.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (nu, rows) in &mut curves {
            rows.sort_by(|a, b| a.0.total_cmp(&b.0));
            if rows.len() < 2
                || rows
                    .windows(2)
                    .any(|w| w[1].0 <= w[0].0 || w[1].1 <= w[0].1)
            {
                return Err(format!(
                    "ν = {nu}: needs ≥ 2 rows with δ/R and F strictly increasing"
                ));
            }
        }
        Ok(Self { curves })
    }

    /// The shipped table.
    pub fn load() -> Self {
        Self::parse(FINITE_SPHERE_TABLE_CSV)
            .unwrap_or_else(|e| panic!("{FINITE_SPHERE_TABLE_PATH}: {e}"))
    }

    /// Smallest and largest tabulated ν.
    pub fn nu_range(&self) -> (f64, f64) {
        (self.curves[0].0, self.curves[self.curves.len() - 1].0)
    }

    /// The reference curve at Poisson ratio ν, `None` outside [`Self::nu_range`].
    pub fn at_poisson_ratio(&self, nu: f64) -> Option<FiniteSphereReference> {
        let c = &self.curves;
        let k = c.iter().position(|q| q.0 >= nu)?;
        if c[k].0 == nu {
            return Some(FiniteSphereReference {
                lo: c[k].1.clone(),
                hi: c[k].1.clone(),
                weight: 0.0,
            });
        }
        if k == 0 {
            return None;
        }
        Some(FiniteSphereReference {
            lo: c[k - 1].1.clone(),
            hi: c[k].1.clone(),
            weight: (nu - c[k - 1].0) / (c[k].0 - c[k - 1].0),
        })
    }
}

/// The finite-sphere reference at one ν (see [`FiniteSphereTable`]).
#[derive(Debug, Clone)]
pub struct FiniteSphereReference {
    /// The two bracketing tabulated curves and the weight of `hi` (0 on a tabulated ν).
    lo: Vec<Row>,
    hi: Vec<Row>,
    weight: f64,
}

/// Log–log interpolation of F/(E*R²) at ln(δ/R) = x along one tabulated curve.
fn log_log(rows: &[Row], x: f64) -> Option<f64> {
    if x < rows[0].0 || x > rows[rows.len() - 1].0 {
        return None;
    }
    let k = rows.partition_point(|q| q.0 <= x).clamp(1, rows.len() - 1);
    let (x0, y0, _) = rows[k - 1];
    let (x1, y1, _) = rows[k];
    Some((y0 + (x - x0) / (x1 - x0) * (y1 - y0)).exp())
}

impl FiniteSphereReference {
    /// F/(E*R²) at δ/R; `None` outside the tabulated δ/R range.
    pub fn dimensionless_force(&self, delta_over_r: f64) -> Option<f64> {
        if delta_over_r.is_nan() || delta_over_r <= 0.0 {
            return None;
        }
        let x = delta_over_r.ln();
        let lo = log_log(&self.lo, x)?;
        let hi = log_log(&self.hi, x)?;
        Some(lo + self.weight * (hi - lo))
    }

    /// Range of F/(E*R²) the curve covers (both bracketing curves defined).
    pub fn dimensionless_force_range(&self) -> (f64, f64) {
        let x0 = self.lo[0].0.max(self.hi[0].0);
        let x1 = self.lo[self.lo.len() - 1]
            .0
            .min(self.hi[self.hi.len() - 1].0);
        (
            self.dimensionless_force(x0.exp()).unwrap_or(f64::NAN),
            self.dimensionless_force(x1.exp()).unwrap_or(f64::NAN),
        )
    }

    /// F_ref(δ) (N) for a sphere of `radius` and `material`; `None` outside the table.
    pub fn force(&self, material: &ElasticParameters, radius: f64, delta: f64) -> Option<f64> {
        self.dimensionless_force(delta / radius)
            .map(|f| f * material.plane_strain_modulus() * radius * radius)
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
    /// Masing branch from a reversal at (δ*, Q*): Q = Q* − 2 Q_load((δ* − δ)/2), ending in
    /// gross sliding (|Q| ≤ μN; from Q* < μN the branch reaches ∓μN before its argument
    /// reaches δt,max). Serves unloading and reloading alike (the sign follows δ* − δ).
    pub fn unloading(&self, reversal_dt: f64, reversal_q: f64, dt: f64) -> f64 {
        let mu_n = self.mu * self.normal_force;
        (reversal_q - 2.0 * self.loading(0.5 * (reversal_dt - dt))).clamp(-mu_n, mu_n)
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

/// Rolling about a fixed centre under constant N (docs/THEORY.md §4): δt = Rθ at the contact, so
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
        // docs/THEORY.md §1 table: the formulas, evaluated, agree with the printed values.
        let m = ElasticParameters::paper_glass();
        let pair = Hertz::identical_spheres(&m, 1.1e-3);
        let flat = Hertz::sphere_on_flat(&m, 1.1e-3);
        assert!((pair.force(1e-6) - 1.035).abs() < 0.002);
        assert!((flat.force(10e-6) - 92.58).abs() < 0.05);
        assert!((pair.contact_radius(pair.force(5e-6)) - 52.44e-6).abs() < 0.02e-6);
    }

    /// Parses the original dimensional table (R = 1.1 mm, E = 63 GPa, ν = 0.22):
    /// (δ/R, F/(E*R²)).
    fn original_table() -> Vec<(f64, f64)> {
        let m = ElasticParameters::paper_glass();
        let (r, e_star) = (1.1e-3, m.plane_strain_modulus());
        FINITE_SPHERE_CSV
            .lines()
            .filter_map(|line| {
                let cols: Vec<&str> = line.split(',').collect();
                let d = cols.first()?.trim().parse::<f64>().ok()?;
                let f = cols.get(1)?.trim().parse::<f64>().ok()?;
                Some((d * 1e-6 / r, f / (e_star * r * r)))
            })
            .collect()
    }

    #[test]
    fn table_at_nu_022_matches_the_original_reference() {
        let table = FiniteSphereTable::load();
        let r = table.at_poisson_ratio(0.22).expect("ν = 0.22 in the table");
        // every original row inside the table's δ/R range (which covers the validation
        // window)
        let mut compared = 0;
        for (d, f) in original_table() {
            if let Some(g) = r.dimensionless_force(d) {
                assert!((g / f - 1.0).abs() < 1e-3, "δ/R = {d}: {g} vs {f}");
                compared += 1;
            }
        }
        assert!(compared >= 18, "{compared} rows compared");
    }

    #[test]
    fn finite_sphere_reference_scales_and_exceeds_hertz() {
        let m = ElasticParameters::paper_glass();
        let r = FiniteSphereTable::load().at_poisson_ratio(0.22).unwrap();
        assert!((r.force(&m, 1.1e-3, 5e-6).unwrap() / 33.7846 - 1.0).abs() < 1e-3);
        let flat = Hertz::sphere_on_flat(&m, 1.1e-3);
        let ratio = r.force(&m, 1.1e-3, 2e-6).unwrap() / flat.force(2e-6);
        assert!(ratio > 1.0 && ratio < 1.03);
        assert!(r.force(&m, 1.1e-3, 1e-3).is_none());
        // similarity: twice the radius, twice E → F × 8 at twice δ
        let m2 = ElasticParameters {
            youngs_modulus: 2.0 * m.youngs_modulus,
            ..m
        };
        let f1 = r.force(&m, 1.1e-3, 3e-6).unwrap();
        let f2 = r.force(&m2, 2.2e-3, 6e-6).unwrap();
        assert!((f2 / (8.0 * f1) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn table_interpolates_linearly_in_nu_and_refuses_outside() {
        let text = "# test\nnu,delta_over_R,F_over_EstarR2,a_over_R\n\
                    0.2,1e-4,1e-6,0.01\n0.2,1e-2,1e-3,0.1\n\
                    0.3,1e-4,2e-6,0.01\n0.3,1e-2,2e-3,0.1\n";
        let t = FiniteSphereTable::parse(text).unwrap();
        assert_eq!(t.nu_range(), (0.2, 0.3));
        let r = t.at_poisson_ratio(0.25).unwrap();
        // log–log along δ/R: the midpoint in ln δ is the geometric mean in F
        let mid = r.dimensionless_force(1e-3).unwrap();
        let expect = 0.5 * (1e-6f64 * 1e-3).sqrt() + 0.5 * (2e-6f64 * 2e-3).sqrt();
        assert!((mid / expect - 1.0).abs() < 1e-12, "{mid} {expect}");
        assert!(t.at_poisson_ratio(0.35).is_none());
        assert!(t.at_poisson_ratio(0.1).is_none());
        assert!(r.dimensionless_force(2e-2).is_none());
        assert!(FiniteSphereTable::parse("nu,x\n").is_err());
        assert!(FiniteSphereTable::parse(
            "nu,delta_over_R,F_over_EstarR2,a_over_R\n0.2,1e-4,1e-6,0.01\n"
        )
        .is_err());
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
        // docs/THEORY.md §3: c/a = 0.6 → M/(μNa) = 0.481, G a² β/(μN) = 0.1716
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
