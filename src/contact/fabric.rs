//! Grain-pair contacts from the node-level contact points of the last evaluation: the
//! quantities granular mechanics works with (force chains, fabric tensor, sliding
//! contacts), as opposed to the penalty points the solver works with.
//!
//! A pair (a, b), a < b by global id, is in contact when any point of either pass (nodes
//! of a on b's surface, nodes of b on a's) is active. Its force is the sum of its points'
//! forces (on a), its point the points' positions weighted by their normal force, its
//! normal the points' master normals weighted the same way and oriented from a to b. It
//! slides when every active point of it is on the Coulomb cone (gross sliding; a Mindlin
//! contact with a slipping annulus and a sticking centre does not).
//!
//! Each rank sees the passes whose slave grain it owns, so a pair may come in two
//! partials from two ranks: [`PairPartial`]s are gathered and merged by [`merge_pairs`].
//!
//! In a periodic cell two grains may touch through several images (in a one-cell FCC
//! cell, each pair four times): a pair is (a, b, image of b seen from a), and its point is
//! given where a itself is.

use super::ContactScratch;
use crate::math::{add, dot, norm, scale, sub};
use crate::model::periodic::{relative_image, CellKinematics, Image};
use crate::model::Model;

/// One rank's share of a pair's contact points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairPartial {
    pub a: u32,
    pub b: u32,
    /// Periodic image of b relative to a (all zero without a cell).
    pub image: Image,
    /// Force on grain a (N).
    pub force_on_a: [f64; 3],
    /// Σ wᵢ xᵢ over points (N·m), w = normal force.
    pub weighted_point: [f64; 3],
    /// Σ wᵢ nᵢ, normals oriented a → b (N).
    pub weighted_normal: [f64; 3],
    /// Σ wᵢ (N).
    pub weight: f64,
    pub points: u32,
    pub sliding_points: u32,
}

/// Values per partial in [`PairPartial::encode`].
pub const PARTIAL_LEN: usize = 17;

impl PairPartial {
    /// As f64s, for a gather over ranks (ids are exact in f64 below 2⁵³).
    pub fn encode(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&[self.a as f64, self.b as f64]);
        out.extend_from_slice(&self.image.map(f64::from));
        out.extend_from_slice(&self.force_on_a);
        out.extend_from_slice(&self.weighted_point);
        out.extend_from_slice(&self.weighted_normal);
        out.extend_from_slice(&[self.weight, self.points as f64, self.sliding_points as f64]);
    }

    pub fn decode(v: &[f64]) -> Self {
        let v3 = |k: usize| [v[k], v[k + 1], v[k + 2]];
        Self {
            a: v[0] as u32,
            b: v[1] as u32,
            image: [v[2] as i8, v[3] as i8, v[4] as i8],
            force_on_a: v3(5),
            weighted_point: v3(8),
            weighted_normal: v3(11),
            weight: v[14],
            points: v[15] as u32,
            sliding_points: v[16] as u32,
        }
    }

    /// The pair: (a, b, image of b relative to a).
    pub fn key(&self) -> (u32, u32, Image) {
        (self.a, self.b, self.image)
    }

    fn absorb(&mut self, o: &PairPartial) {
        self.force_on_a = add(self.force_on_a, o.force_on_a);
        self.weighted_point = add(self.weighted_point, o.weighted_point);
        self.weighted_normal = add(self.weighted_normal, o.weighted_normal);
        self.weight += o.weight;
        self.points += o.points;
        self.sliding_points += o.sliding_points;
    }
}

/// A grain-pair contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairContact {
    pub a: u32,
    pub b: u32,
    /// Periodic image of b relative to a (all zero without a cell).
    pub image: Image,
    /// Contact point (m).
    pub point: [f64; 3],
    /// Unit normal from a to b.
    pub normal: [f64; 3],
    /// Compressive normal force (N, b pushing a: −force_on_a·normal).
    pub normal_force: f64,
    /// Magnitude of the tangential force (N).
    pub tangential_force: f64,
    pub sliding: bool,
}

/// This rank's partials from the last contact evaluation (owned slave grains only), in
/// `out` (cleared first), sorted by (a, b, image) with one entry per pair; `cell` places
/// the images.
pub fn pair_partials(
    model: &Model,
    x: &[[f64; 3]],
    scratch: &ContactScratch,
    cell: &CellKinematics,
    out: &mut Vec<PairPartial>,
) {
    out.clear();
    let cm = &model.contact;
    let lists = &scratch.lists;
    for r in &scratch.results {
        if !r.active {
            continue;
        }
        let pass = lists.passes[r.pass as usize];
        let (slave, master) = (
            &cm.surfaces[pass.slave as usize],
            &cm.surfaces[pass.master as usize],
        );
        if !slave.owned {
            continue;
        }
        // the master's outward normal points from master to slave
        let slave_is_a = (slave.global_id, slave.image) < (master.global_id, master.image);
        let (a, b, sign) = if slave_is_a {
            (slave, master, 1.0)
        } else {
            (master, slave, -1.0)
        };
        let w = r.pressure * r.area;
        // the point where a itself is (not its image)
        let point = sub(x[r.slave as usize], cell.offset(a.image));
        let p = PairPartial {
            a: a.global_id,
            b: b.global_id,
            image: relative_image(a.image, b.image),
            force_on_a: scale(r.force, sign),
            weighted_point: scale(point, w),
            weighted_normal: scale(r.normal, -sign * w),
            weight: w,
            points: 1,
            sliding_points: u32::from(r.sliding),
        };
        match out.last_mut() {
            Some(last) if last.key() == p.key() => last.absorb(&p),
            _ => out.push(p),
        }
    }
    merge_sorted(out);
}

/// Sorts partials by pair and merges duplicates in place.
fn merge_sorted(parts: &mut Vec<PairPartial>) {
    parts.sort_by_key(|p| p.key());
    let mut kept = 0;
    for i in 0..parts.len() {
        if kept > 0 && parts[kept - 1].key() == parts[i].key() {
            let p = parts[i];
            parts[kept - 1].absorb(&p);
        } else {
            parts[kept] = parts[i];
            kept += 1;
        }
    }
    parts.truncate(kept);
}

/// The pair contacts from all ranks' partials (their encodings concatenated), by (a, b,
/// image).
pub fn merge_pairs(encoded: &[f64]) -> Vec<PairContact> {
    let mut parts: Vec<PairPartial> = encoded
        .chunks_exact(PARTIAL_LEN)
        .map(PairPartial::decode)
        .collect();
    merge_sorted(&mut parts);
    parts
        .iter()
        .filter(|p| p.weight > 0.0)
        .map(|p| {
            let n = scale(
                p.weighted_normal,
                1.0 / norm(p.weighted_normal).max(f64::MIN_POSITIVE),
            );
            let f_n = -dot(p.force_on_a, n);
            let f_t = sub(p.force_on_a, scale(n, -f_n));
            PairContact {
                a: p.a,
                b: p.b,
                image: p.image,
                point: scale(p.weighted_point, 1.0 / p.weight),
                normal: n,
                normal_force: f_n,
                tangential_force: norm(f_t),
                sliding: p.sliding_points == p.points,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn partial(a: u32, b: u32, f: [f64; 3], w: f64, n: [f64; 3], sliding: bool) -> PairPartial {
        PairPartial {
            a,
            b,
            image: [0; 3],
            force_on_a: f,
            weighted_point: [w, 0.0, 0.0],
            weighted_normal: scale(n, w),
            weight: w,
            points: 1,
            sliding_points: u32::from(sliding),
        }
    }

    #[test]
    fn partials_of_two_ranks_merge_into_one_pair() {
        // a pushed by b along −x with 3 N normal and 0.4 N tangential in total
        let mut enc = Vec::new();
        partial(1, 4, [-2.0, 0.3, 0.0], 2.0, [1.0, 0.0, 0.0], true).encode(&mut enc);
        partial(0, 2, [-1.0, 0.0, 0.0], 1.0, [1.0, 0.0, 0.0], false).encode(&mut enc);
        partial(1, 4, [-1.0, 0.1, 0.0], 1.0, [1.0, 0.0, 0.0], false).encode(&mut enc);
        let pairs = merge_pairs(&enc);
        assert_eq!(pairs.len(), 2);
        let p = pairs[1];
        assert_eq!((p.a, p.b), (1, 4));
        assert!((p.normal_force - 3.0).abs() < 1e-15);
        assert!((p.tangential_force - 0.4).abs() < 1e-15);
        assert!(!p.sliding, "one of its points sticks");
        assert!(pairs[0].normal_force > 0.0 && !pairs[0].sliding);
        let both = merge_pairs(&{
            let mut e = Vec::new();
            partial(1, 4, [-2.0, 0.8, 0.0], 2.0, [1.0, 0.0, 0.0], true).encode(&mut e);
            e
        });
        assert!(both[0].sliding);
    }
}
