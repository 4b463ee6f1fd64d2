//! Diagnostics for failed runs: which element to blame when the energy explodes.

use crate::element::tet_forces;
use crate::model::Model;

/// The element with the largest strain energy density at positions `x`, with that
/// density (J/m³); non-finite values rank highest. Only called after a failure.
pub fn most_strained_element(model: &Model, x: &[[f64; 3]]) -> (usize, f64) {
    let mut worst = (0, f64::NEG_INFINITY);
    for (e, t) in model.tets.iter().enumerate() {
        let xe = t.map(|n| x[n as usize]);
        let r = &model.tet_reference[e];
        let ef = tet_forces(&xe, r, &model.laws[model.tet_law[e] as usize]);
        let density = ef.strain_energy / r.volume;
        let key = if density.is_finite() {
            density
        } else {
            f64::INFINITY
        };
        if key > worst.1 {
            worst = (e, key);
        }
    }
    worst
}
