//! Hertz theory of elliptical contact (Johnson, *Contact Mechanics*, §4.2): a convex
//! elastic tip with principal radii R₁ ≥ R₂ pressed on a rigid flat by a force P.
//!
//! With relative curvatures A = 1/(2R₁) ≤ B = 1/(2R₂) the contact is an ellipse of
//! semi-axes a ≥ b (a along the flatter direction, R₁), eccentricity e = √(1 − b²/a²),
//! pressure p = p₀ √(1 − x²/a² − y²/b²) with p₀ = 3P/(2πab). The surface displacement under
//! that pressure is u_z = (L − M x² − N y²)/(πE*), L = π p₀ b K(e),
//! M = π p₀ b (K − E)/(e² a²), N = π p₀ b ((a²/b²) E − K)/(e² a²), and contact with the flat
//! requires M/(πE*) = A, N/(πE*) = B, L/(πE*) = δ. Hence
//!
//! - the shape: B/A = ((a/b)² E(e) − K(e)) / (K(e) − E(e)), independent of the load;
//! - the size: a³ = 3P (K − E)/(2π E* e² A), b = a √(1 − e²);
//! - the approach: δ = 3P K/(2π a E*), so P ∝ δ^{3/2} as for a sphere.
//!
//! K, E are the complete elliptic integrals of the first and second kind of modulus e,
//! E* = E/(1 − ν²) on a rigid flat. For R₁ = R₂ = R this is the sphere: a = b =
//! (3PR/(4E*))^{1/3}, δ = a²/R.

use std::f64::consts::PI;

/// Complete elliptic integrals (K(k), E(k)) of modulus k ∈ [0, 1), by the
/// arithmetic–geometric mean (quadratic convergence: machine precision in ≤ 6 rounds for
/// k ≤ 0.999).
pub fn complete_elliptic(k: f64) -> (f64, f64) {
    let (mut a, mut b) = (1.0_f64, (1.0 - k * k).sqrt());
    let mut c = k;
    let mut sum = 0.5 * c * c;
    let mut weight = 0.5;
    for _ in 0..40 {
        if c.abs() < 1e-17 {
            break;
        }
        let (an, bn) = (0.5 * (a + b), (a * b).sqrt());
        c = 0.5 * (a - b);
        weight *= 2.0;
        sum += weight * c * c;
        a = an;
        b = bn;
    }
    let kk = PI / (2.0 * a);
    (kk, kk * (1.0 - sum))
}

/// Hertz elliptical contact of one tip on a rigid flat.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EllipticHertz {
    /// Principal radii of the tip, R₁ ≥ R₂ (m).
    pub r1: f64,
    pub r2: f64,
    /// E* = E/(1 − ν²) (Pa).
    pub e_star: f64,
    /// Eccentricity of the contact ellipse (–).
    pub eccentricity: f64,
    /// K(e), E(e).
    k: f64,
    e: f64,
    /// (K − E)/e², kept finite as e → 0 (π/4).
    k_minus_e_over_e2: f64,
}

impl EllipticHertz {
    /// The contact of a tip with principal radii `r1`, `r2` (any order) on a rigid flat.
    pub fn new(r1: f64, r2: f64, e_star: f64) -> Self {
        let (r1, r2) = (r1.max(r2), r1.min(r2));
        let ratio = r1 / r2; // B/A ≥ 1
        let eccentricity = solve_eccentricity(ratio);
        let (k, e) = complete_elliptic(eccentricity);
        let e2 = eccentricity * eccentricity;
        let k_minus_e_over_e2 = if e2 < 1e-8 {
            // K − E = (π/2)(e²/2 + 3e⁴/16 + …)
            PI / 4.0 * (1.0 + 0.375 * e2)
        } else {
            (k - e) / e2
        };
        Self {
            r1,
            r2,
            e_star,
            eccentricity,
            k,
            e,
            k_minus_e_over_e2,
        }
    }

    /// Equivalent radius √(R₁R₂) (m).
    pub fn equivalent_radius(&self) -> f64 {
        (self.r1 * self.r2).sqrt()
    }

    /// Minor over major semi-axis of the contact ellipse, b/a = √(1 − e²).
    pub fn axis_ratio(&self) -> f64 {
        (1.0 - self.eccentricity * self.eccentricity).sqrt()
    }

    /// Semi-axes (a, b) of the contact ellipse at force P (m).
    pub fn semi_axes(&self, force: f64) -> (f64, f64) {
        let curvature_a = 0.5 / self.r1;
        let a =
            (3.0 * force * self.k_minus_e_over_e2 / (2.0 * PI * self.e_star * curvature_a)).cbrt();
        (a, a * self.axis_ratio())
    }

    /// Approach of the flat to distant points of the body at force P (m).
    pub fn approach(&self, force: f64) -> f64 {
        if force <= 0.0 {
            return 0.0;
        }
        let (a, _) = self.semi_axes(force);
        3.0 * force * self.k / (2.0 * PI * a * self.e_star)
    }

    /// Force at approach δ (N): the inverse of [`EllipticHertz::approach`], P ∝ δ^{3/2}.
    pub fn force(&self, approach: f64) -> f64 {
        if approach <= 0.0 {
            return 0.0;
        }
        approach.powf(1.5) / self.approach(1.0).powf(1.5)
    }

    /// Force at which √(ab) = `size` (N): the load of a given equivalent contact radius.
    pub fn force_at_equivalent_radius(&self, size: f64) -> f64 {
        let (a1, b1) = self.semi_axes(1.0);
        (size * size / (a1 * b1)).powf(1.5)
    }

    /// Peak pressure p₀ = 3P/(2πab) (Pa).
    pub fn peak_pressure(&self, force: f64) -> f64 {
        let (a, b) = self.semi_axes(force);
        3.0 * force / (2.0 * PI * a * b)
    }

    /// K(e) and E(e) of the contact ellipse.
    pub fn elliptic_integrals(&self) -> (f64, f64) {
        (self.k, self.e)
    }
}

/// The eccentricity e whose ellipse has B/A = `ratio` ≥ 1 (bisection on the monotonic
/// relation; e = 0 for a circle).
fn solve_eccentricity(ratio: f64) -> f64 {
    if ratio <= 1.0 + 1e-12 {
        return 0.0;
    }
    let curvature_ratio = |ecc: f64| {
        let (k, e) = complete_elliptic(ecc);
        ((e / (1.0 - ecc * ecc)) - k) / (k - e)
    };
    let (mut lo, mut hi) = (1e-6_f64, 1.0 - 1e-15);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if curvature_ratio(mid) < ratio {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-15 {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The surface displacement (times πE*) at (x0, y0) under p₀ √(1 − x²/a² − y²/b²),
    /// ∫∫ p/ρ dA, by quadrature in polar coordinates about the point (the 1/ρ cancels the
    /// Jacobian): an independent check of the closed forms above.
    fn displacement_integral(p0: f64, a: f64, b: f64, x0: f64, y0: f64) -> f64 {
        let n_theta = 2000;
        let n_s = 400;
        let mut total = 0.0;
        for i in 0..n_theta {
            let th = 2.0 * PI * (i as f64 + 0.5) / n_theta as f64;
            let (c, s) = (th.cos(), th.sin());
            // 1 − (x0 + t c)²/a² − (y0 + t s)²/b² = α − 2βt − γt²
            let gamma = c * c / (a * a) + s * s / (b * b);
            let beta = x0 * c / (a * a) + y0 * s / (b * b);
            let alpha = 1.0 - x0 * x0 / (a * a) - y0 * y0 / (b * b);
            let t_max = (-beta + (beta * beta + alpha * gamma).sqrt()) / gamma;
            // t = t_max (1 − u²) removes the square-root end point
            let mut ray = 0.0;
            for j in 0..n_s {
                let u = (j as f64 + 0.5) / n_s as f64;
                let t = t_max * (1.0 - u * u);
                let q = (alpha - 2.0 * beta * t - gamma * t * t).max(0.0);
                ray += q.sqrt() * 2.0 * t_max * u / n_s as f64;
            }
            total += p0 * ray * 2.0 * PI / n_theta as f64;
        }
        total
    }

    #[test]
    fn elliptic_integrals_match_known_values() {
        let (k, e) = complete_elliptic(0.0);
        assert!((k - PI / 2.0).abs() < 1e-15 && (e - PI / 2.0).abs() < 1e-15);
        // K(1/√2) = Γ(1/4)²/(4√π), E(1/√2) = (K² ... ) via Legendre: 2EK − K² = π/2
        let (k, e) = complete_elliptic(std::f64::consts::FRAC_1_SQRT_2);
        assert!((k - 1.854_074_677_301_372).abs() < 1e-13);
        assert!((2.0 * e * k - k * k - PI / 2.0).abs() < 1e-13);
        // Legendre's relation E K' + E' K − K K' = π/2 at another modulus
        let m = 0.83_f64;
        let (k1, e1) = complete_elliptic(m);
        let (k2, e2) = complete_elliptic((1.0 - m * m).sqrt());
        assert!((e1 * k2 + e2 * k1 - k1 * k2 - PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn equal_radii_give_the_sphere() {
        let (r, es, p) = (1.3e-3, 7.1e10, 4.2);
        let h = EllipticHertz::new(r, r, es);
        let a = (3.0 * p * r / (4.0 * es)).cbrt();
        let (a1, b1) = h.semi_axes(p);
        assert!((a1 / a - 1.0).abs() < 1e-12 && (b1 / a - 1.0).abs() < 1e-12);
        assert!((h.approach(p) / (a * a / r) - 1.0).abs() < 1e-12);
        // and a nearly circular tip is continuous with it
        let h = EllipticHertz::new(r * (1.0 + 1e-9), r, es);
        assert!((h.approach(p) / (a * a / r) - 1.0).abs() < 1e-6);
    }

    /// The contact conditions hold: under the Hertz pressure of the computed ellipse the
    /// surface displacement is δ − A x² − B y² (quadrature), for several curvature ratios.
    #[test]
    fn the_pressure_makes_the_surface_fit_the_tip() {
        let es = 6.6e10;
        for (r1, r2) in [(2.0e-3, 1.0e-3), (5.0e-3, 0.8e-3), (1.2e-3, 1.1e-3)] {
            let h = EllipticHertz::new(r1, r2, es);
            let p = 3.0;
            let (a, b) = h.semi_axes(p);
            let p0 = h.peak_pressure(p);
            let u = |x: f64, y: f64| displacement_integral(p0, a, b, x, y) / (PI * es);
            let delta = h.approach(p);
            assert!(
                (u(0.0, 0.0) / delta - 1.0).abs() < 2e-4,
                "δ at R₁/R₂ = {}",
                r1 / r2
            );
            for (x, y) in [(0.5 * a, 0.0), (0.0, 0.6 * b), (0.3 * a, 0.4 * b)] {
                let gap = delta - x * x / (2.0 * r1) - y * y / (2.0 * r2);
                assert!(
                    (u(x, y) - gap).abs() < 3e-4 * delta,
                    "u({x:e}, {y:e}) = {:e} vs {gap:e} at R₁/R₂ = {}",
                    u(x, y),
                    r1 / r2
                );
            }
            // P ∝ δ^{3/2}, and the equivalent-radius load inverts √(ab)
            assert!((h.force(h.approach(7.0)) / 7.0 - 1.0).abs() < 1e-12);
            let f = h.force_at_equivalent_radius((a * b).sqrt());
            assert!((f / p - 1.0).abs() < 1e-12);
        }
    }

    /// Johnson's approximation b/a ≈ (A/B)^{2/3} (within a few % for moderate ratios).
    #[test]
    fn axis_ratio_follows_the_two_thirds_rule_of_thumb() {
        for ratio in [1.5, 2.0, 3.0] {
            let h = EllipticHertz::new(ratio, 1.0, 1.0);
            let approx = ratio.powf(-2.0 / 3.0);
            assert!((h.axis_ratio() / approx - 1.0).abs() < 0.04, "{ratio}");
        }
    }
}
