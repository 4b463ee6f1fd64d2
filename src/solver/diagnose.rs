//! Diagnostics for failed runs: which element to blame when the energy explodes.

use super::forces::element_response;
use crate::material::PlasticPoint;
use crate::model::Model;

/// The element with the largest strain energy density at positions `x`, with that
/// density (J/m³); non-finite values rank highest. Only called after a failure.
pub fn most_strained_element(
    model: &Model,
    x: &[[f64; 3]],
    plastic: &[PlasticPoint],
) -> (usize, f64) {
    let mut worst = (0, f64::NEG_INFINITY);
    for e in 0..model.owned_elements {
        let density = element_response(model, x, plastic, e).1.stored_energy;
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
