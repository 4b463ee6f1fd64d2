//! Deterministic test inputs (no `rand` dependency needed).

use crate::grain::GrainInfo;

/// Small linear congruential generator (Knuth's MMIX constants); good enough
/// to scatter test grains reproducibly.
pub(crate) struct Lcg(u64);

impl Lcg {
    pub(crate) fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [0, 1).
    pub(crate) fn next_f64(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Identical grains at the given centres.
pub(crate) fn uniform_grains(
    centres: &[[f64; 3]],
    radius: f64,
    elements: usize,
    surface_nodes: usize,
) -> Vec<GrainInfo> {
    centres
        .iter()
        .map(|&centre| GrainInfo {
            centre,
            bounding_radius: radius,
            elements,
            surface_nodes,
        })
        .collect()
}

/// `n` grains with radii in [0.05, 0.15) scattered in a box sized so that
/// most grains have a few neighbours; mesh sizes scale with the radius.
pub(crate) fn polydisperse_grains(n: usize, seed: u64) -> Vec<GrainInfo> {
    let mut rng = Lcg::new(seed);
    let side = 0.2 * (n as f64).cbrt();
    (0..n)
        .map(|_| {
            let radius = 0.05 + 0.1 * rng.next_f64();
            let centre = [
                side * rng.next_f64(),
                side * rng.next_f64(),
                side * rng.next_f64(),
            ];
            let scale = (radius / 0.1).powi(2);
            GrainInfo {
                centre,
                bounding_radius: radius,
                elements: (4000.0 * scale) as usize + 10,
                surface_nodes: (800.0 * scale) as usize + 4,
            }
        })
        .collect()
}
