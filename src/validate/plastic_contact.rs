//! Closed-form references for an elastic–perfectly plastic sphere pressed on a rigid flat
//! (docs/THEORY.md §6): Jackson–Green (2005), the fit `plastic_spheres` is validated
//! against, and Kogut–Etsion (2002), reported beside it. Both are evaluated for the
//! material and radius of the scene as run.

/// Jackson–Green (2005): first yield and the F–δ fit of an elastic–perfectly plastic
/// sphere on a rigid flat (docs/THEORY.md §6). δ is the interference of one sphere.
#[derive(Debug, Clone, Copy)]
pub struct JacksonGreen {
    /// E' = E/(1−ν²) (Pa).
    pub e_prime: f64,
    pub poisson_ratio: f64,
    /// σy (Pa).
    pub yield_stress: f64,
    /// R (m).
    pub radius: f64,
    /// C(ν) = 1.295 exp(0.736 ν).
    pub c: f64,
    /// δc (m).
    pub delta_c: f64,
    /// Pc (N).
    pub p_c: f64,
    /// ac (m).
    pub a_c: f64,
}

impl JacksonGreen {
    pub fn new(young: f64, poisson_ratio: f64, yield_stress: f64, radius: f64) -> Self {
        let e_prime = young / (1.0 - poisson_ratio * poisson_ratio);
        let c = 1.295 * (0.736 * poisson_ratio).exp();
        let k = std::f64::consts::PI * c * yield_stress / 2.0;
        Self {
            e_prime,
            poisson_ratio,
            yield_stress,
            radius,
            c,
            delta_c: (k / e_prime).powi(2) * radius,
            p_c: 4.0 / 3.0 * (radius / e_prime).powi(2) * k.powi(3),
            a_c: k * radius / e_prime,
        }
    }

    /// Exponent B = 0.14 exp(23 σy/E') of the contact-radius growth.
    pub fn b(&self) -> f64 {
        0.14 * (23.0 * self.yield_stress / self.e_prime).exp()
    }

    /// Contact radius a = √(R δ (δ*/1.9)^B) beyond δ* = 1.9, Hertz √(Rδ) below (m).
    pub fn contact_radius(&self, delta: f64) -> f64 {
        let ds = delta / self.delta_c;
        let hertz = (self.radius * delta.max(0.0)).sqrt();
        if ds <= 1.9 {
            hertz
        } else {
            hertz * (ds / 1.9).powf(0.5 * self.b())
        }
    }

    /// Hardness ratio H_G/σy = 2.84 [1 − exp(−0.82 (a/R)^−0.7)].
    pub fn hardness_ratio(&self, a: f64) -> f64 {
        2.84 * (1.0 - (-0.82 * (a / self.radius).powf(-0.7)).exp())
    }

    /// P/Pc at δ* (Hertz δ*^{3/2} up to 1.9).
    pub fn force_ratio(&self, ds: f64) -> f64 {
        if ds <= 1.9 {
            return ds.max(0.0).powf(1.5);
        }
        let a = self.contact_radius(ds * self.delta_c);
        (-0.25 * ds.powf(5.0 / 12.0)).exp() * ds.powf(1.5)
            + 4.0 * self.hardness_ratio(a) / self.c
                * (1.0 - (-ds.powf(5.0 / 9.0) / 25.0).exp())
                * ds
    }

    /// F_JG(δ) (N).
    pub fn force(&self, delta: f64) -> f64 {
        self.p_c * self.force_ratio(delta / self.delta_c)
    }

    /// Elastic recovery δm − δres on unloading from δm, from the Hertz unloading of the
    /// flattened tip through (δm, F_JG, a_JG): 3 F/(4 E' a) (m).
    pub fn elastic_recovery(&self, delta_m: f64) -> f64 {
        3.0 * self.force(delta_m) / (4.0 * self.e_prime * self.contact_radius(delta_m))
    }

    /// Hertz F = (4/3) E' √R δ^{3/2} = Pc δ*^{3/2} (N).
    pub fn hertz(&self, delta: f64) -> f64 {
        self.p_c * (delta.max(0.0) / self.delta_c).powf(1.5)
    }
}

/// Kogut–Etsion (2002) for comparison: K = 0.454 + 0.41ν, H = 2.8σy, ωc = (πKH/(2E'))² R,
/// P/Pc,KE = 1.03 ω*^1.425 (1–6), 1.40 ω*^1.263 (6–110), Hertz below 1.
#[derive(Debug, Clone, Copy)]
pub struct KogutEtsion {
    pub omega_c: f64,
    pub p_c: f64,
}

impl KogutEtsion {
    pub fn new(young: f64, poisson_ratio: f64, yield_stress: f64, radius: f64) -> Self {
        let e_prime = young / (1.0 - poisson_ratio * poisson_ratio);
        let k = 0.454 + 0.41 * poisson_ratio;
        let omega_c =
            (std::f64::consts::PI * k * 2.8 * yield_stress / (2.0 * e_prime)).powi(2) * radius;
        Self {
            omega_c,
            p_c: 4.0 / 3.0 * e_prime * radius.sqrt() * omega_c.powf(1.5),
        }
    }

    /// F_KE(δ) (N).
    pub fn force(&self, delta: f64) -> f64 {
        let w = delta.max(0.0) / self.omega_c;
        self.p_c
            * if w <= 1.0 {
                w.powf(1.5)
            } else if w <= 6.0 {
                1.03 * w.powf(1.425)
            } else {
                1.40 * w.powf(1.263)
            }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// docs/THEORY.md §6: glass with σy = 100 MPa, per sphere.
    #[test]
    fn critical_values_for_glass() {
        let jg = JacksonGreen::new(63e9, 0.22, 1e8, 1.1e-3);
        assert!((jg.c - 1.523).abs() < 1e-3);
        assert!((jg.delta_c - 14.4e-9).abs() < 0.05e-9, "{}", jg.delta_c);
        assert!((jg.p_c - 5.04e-3).abs() < 0.01e-3, "{}", jg.p_c);
        assert!((jg.a_c - 3.97e-6).abs() < 0.01e-6, "{}", jg.a_c);
        // Pc and ac are the Hertz force and radius at δc
        assert!((jg.hertz(jg.delta_c) / jg.p_c - 1.0).abs() < 1e-12);
        assert!((jg.contact_radius(jg.delta_c) / jg.a_c - 1.0).abs() < 1e-12);
    }

    /// The table of docs/THEORY.md §6 (ν = 0.22, σy/E' = 1.5e-3).
    #[test]
    fn jackson_green_and_kogut_etsion_reproduce_the_theory_table() {
        let e_prime = 1.0e11;
        let nu: f64 = 0.22;
        let jg = JacksonGreen::new(e_prime * (1.0 - nu * nu), nu, 1.5e-3 * e_prime, 1.0e-3);
        let ke = KogutEtsion::new(e_prime * (1.0 - nu * nu), nu, 1.5e-3 * e_prime, 1.0e-3);
        let table = [
            (1.5, 1.837, -0.1, 1.00),
            (2.0, 2.878, -3.9, 1.02),
            (3.0, 5.089, -3.1, 0.98),
            (5.0, 10.33, -1.2, 0.92),
            (8.0, 19.60, -1.3, 0.87),
            (10.0, 26.46, -3.0, 0.84),
            (15.0, 45.27, -5.4, 0.78),
            (20.0, 65.85, -6.5, 0.74),
            (30.0, 110.6, -7.1, 0.67),
            (50.0, 209.2, -6.4, 0.59),
        ];
        for (ds, p, ke_minus_jg, over_hertz) in table {
            let d = ds * jg.delta_c;
            let r = jg.force_ratio(ds);
            assert!((r / p - 1.0).abs() < 6e-4, "δ* {ds}: {r} vs {p}");
            let k = 100.0 * (ke.force(d) / jg.force(d) - 1.0);
            assert!((k - ke_minus_jg).abs() < 0.06, "δ* {ds}: KE {k} %");
            let h = jg.force(d) / jg.hertz(d);
            assert!((h - over_hertz).abs() < 0.006, "δ* {ds}: JG/Hertz {h}");
        }
        // the jump of the fit at δ* = 1.9
        assert!((jg.force_ratio(1.9) - 2.619).abs() < 1e-3);
        assert!((jg.force_ratio(1.900_001) - 2.676).abs() < 1e-3);
    }
}
