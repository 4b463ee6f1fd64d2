//! Small fixed-size vector and 3×3 matrix helpers shared by every layer (mesh geometry,
//! elements, contact, prescribed motions). Vectors are `[f64; 3]`; 3×3 matrices are
//! `[f64; 9]` in row-major order, so `m[3 * i + j]` is row i, column j.

use crate::lanes::{dot3, Lanes};

#[inline]
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Mean of `points` (a grain's nodes: the centre its bounds and its wrap are judged by).
pub fn centroid(points: &[[f64; 3]]) -> [f64; 3] {
    let n = points.len() as f64;
    let mut c = [0.0; 3];
    for p in points {
        for i in 0..3 {
            c[i] += p[i] / n;
        }
    }
    c
}

#[inline]
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Row-major 3×3 product a·b.
#[inline(always)]
pub fn mat_mul<T: Lanes>(a: &[T; 9], b: &[T; 9]) -> [T; 9] {
    let mut c = [T::splat(0.0); 9];
    for i in 0..3 {
        for j in 0..3 {
            c[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
        }
    }
    c
}

/// Row-major 3×3 product a·b, each entry by two fused multiply–adds ([`dot3`]): the
/// element kernel's form.
#[inline(always)]
pub fn mat_mul_fused<T: Lanes>(a: &[T; 9], b: &[T; 9]) -> [T; 9] {
    let mut c = [T::splat(0.0); 9];
    for i in 0..3 {
        for j in 0..3 {
            let (r, k) = (3 * i, j);
            c[3 * i + j] = dot3(a[r], b[k], a[r + 1], b[3 + k], a[r + 2], b[6 + k]);
        }
    }
    c
}

/// Determinant of a row-major 3×3 matrix by cofactors in fused multiply–adds: 9 vector
/// operations where [`det3`] takes 14, for the force kernel's det F of every element in
/// every step (elsewhere [`det3`], whose products need no FMA instruction on the portable
/// build).
#[inline(always)]
pub fn det3_fused<T: Lanes>(m: &[T; 9]) -> T {
    let c0 = m[5].neg_mul_add(m[7], m[4] * m[8]);
    let c1 = m[5].neg_mul_add(m[6], m[3] * m[8]);
    let c2 = m[4].neg_mul_add(m[6], m[3] * m[7]);
    m[2].mul_add(c2, m[1].neg_mul_add(c1, m[0] * c0))
}

/// Determinant of a row-major 3×3 matrix.
#[inline(always)]
pub fn det3<T: Lanes>(m: &[T; 9]) -> T {
    m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
        + m[2] * (m[3] * m[7] - m[4] * m[6])
}

/// Two unit vectors spanning the plane normal to the unit vector n (a right-handed
/// triad with n).
pub fn tangent_basis(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let helper = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = cross(n, helper);
    let u = scale(u, 1.0 / norm(u));
    (u, cross(n, u))
}

/// Distance from `p` to the triangle abc.
pub fn point_triangle_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let w = closest_on_triangle(p, a, b, c);
    let q = [0, 1, 2].map(|k| w[0] * a[k] + w[1] * b[k] + w[2] * c[k]);
    norm(sub(p, q))
}

/// Barycentric coordinates (of a, b, c) of the point of the triangle abc closest to `p`
/// (closest-point regions, Ericson §5.1.5).
pub fn closest_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    [1.0 - v - w, v, w]
}

/// splitmix64: a small, well-mixed, reproducible generator (the state is the seed).
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A unit vector uniform on the sphere.
    pub fn direction(&mut self) -> [f64; 3] {
        let z = 2.0 * self.unit() - 1.0;
        let phi = 2.0 * std::f64::consts::PI * self.unit();
        let r = (1.0 - z * z).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fused determinant is the cofactor expansion to round-off, exact on integers,
    /// and keeps the sign of an inverted (mirrored) matrix.
    #[test]
    fn fused_determinant_is_the_determinant() {
        let integers = [2.0, -1.0, 3.0, 0.0, 4.0, 5.0, 1.0, -2.0, 6.0];
        // 2(24 + 10) + 1(0 − 5) + 3(0 − 4) = 68 − 5 − 12
        assert_eq!(det3_fused(&integers), 51.0);
        assert_eq!(det3(&integers), 51.0);
        let mut random = SplitMix64(7);
        for size in [1e-9, 1e-3, 0.3, 2.0] {
            for _ in 0..200 {
                let mut f: [f64; 9] = [0.0; 9];
                for (k, v) in f.iter_mut().enumerate() {
                    *v = size * (2.0 * random.unit() - 1.0) + if k % 4 == 0 { 1.0 } else { 0.0 };
                }
                let scale = f.iter().fold(0.0f64, |m, v| m.max(v.abs())).powi(3);
                assert!((det3_fused(&f) - det3(&f)).abs() <= 16.0 * f64::EPSILON * scale);
                let mirrored = [-f[0], -f[1], -f[2], f[3], f[4], f[5], f[6], f[7], f[8]];
                assert_eq!(det3_fused(&mirrored), -det3_fused(&f));
            }
        }
    }
}
