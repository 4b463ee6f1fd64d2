//! Rigid-body motion of each grain for the records: centroid displacement and the
//! rotation of the best-fitting rigid motion (the rotation factor of the polar
//! decomposition of H = Σ m (x − c)(X − C)ᵀ, which minimises Σ m |x − c − R(X − C)|²).

use crate::model::Model;
use nalgebra::Matrix3;

/// A grain's rigid-body motion since t = 0.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GrainMotion {
    /// Displacement of the mass centre (m).
    pub displacement: [f64; 3],
    /// Rotation vector θ·axis of the best-fitting rotation (rad).
    pub rotation: [f64; 3],
}

/// Motion of grain `g` (an index into `model.grains`) at positions `x`.
pub fn grain_motion(model: &Model, x: &[[f64; 3]], g: usize) -> GrainMotion {
    let nodes = model.grains[g].nodes.clone();
    let (mut mass, mut c, mut c0) = (0.0, [0.0; 3], [0.0; 3]);
    for i in nodes.clone() {
        let m = model.physical_mass[i];
        mass += m;
        for k in 0..3 {
            c[k] += m * x[i][k];
            c0[k] += m * model.x0[i][k];
        }
    }
    let (c, c0) = (c.map(|v| v / mass), c0.map(|v| v / mass));
    let mut h = Matrix3::<f64>::zeros();
    for i in nodes {
        let m = model.physical_mass[i];
        for r in 0..3 {
            for s in 0..3 {
                h[(r, s)] += m * (x[i][r] - c[r]) * (model.x0[i][s] - c0[s]);
            }
        }
    }
    GrainMotion {
        displacement: [0, 1, 2].map(|k| c[k] - c0[k]),
        rotation: rotation_vector(&rotation_of(&h)),
    }
}

/// Rotation factor R of H = R S (S symmetric positive semi-definite), by SVD.
fn rotation_of(h: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let mut r = u * v_t;
    if r.determinant() < 0.0 {
        // the nearest proper rotation: flip the axis of the smallest singular value
        let mut fix = Matrix3::identity();
        let smallest = svd.singular_values.imin();
        fix[(smallest, smallest)] = -1.0;
        r = u * fix * v_t;
    }
    r
}

/// θ·axis of a rotation matrix; accurate at small angles (from its skew part).
fn rotation_vector(r: &Matrix3<f64>) -> [f64; 3] {
    let w = [
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ];
    let s = 0.5 * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt(); // sin θ
    let c = 0.5 * (r.trace() - 1.0); // cos θ
    let angle = s.atan2(c);
    let factor = if s > 1e-12 { angle / (2.0 * s) } else { 0.5 };
    w.map(|v| v * factor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boundary::rotation_from_vector;

    #[test]
    fn recovers_a_rotation_vector_from_its_matrix() {
        for theta in [[0.0, 0.0, 1e-9], [0.3, -0.2, 0.1], [0.0, 2.5, 0.0]] {
            let q = rotation_from_vector(theta);
            let m = Matrix3::from_row_slice(&q);
            let back = rotation_vector(&rotation_of(&m));
            for k in 0..3 {
                assert!((back[k] - theta[k]).abs() < 1e-12, "{theta:?} → {back:?}");
            }
        }
    }
}
