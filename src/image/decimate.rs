//! Coarsening a voxel-fine surface to the seeding by edge collapse, shortest edge first.
//!
//! An edge shorter than [`COLLAPSE_BELOW`] × the seeding is collapsed to its midpoint by
//! [`collapse_short_edges`] (manifold, no facet turned by more than 45° or made worse than
//! its quality bound, no edge grown beyond the seeding). Locked vertices — those a grain shares with a touching grain, and
//! those near them — take part in no collapse and never move: the contact face keeps its
//! voxel-fine, coincident triangles on both grains, and the free surfaces of two grains
//! cannot be pushed through each other next to it.
//! Finally the free vertices move along their normals by the one distance that gives back
//! the volume collapse took away.

use crate::math::{add, cross, norm, scale, sub};
use crate::mesh::collapse::{collapse_short_edges, CollapseRules};
use crate::mesh::import::checks::signed_volume;
use crate::mesh::import::Surface;

/// Edges shorter than this fraction of the seeding are collapsed.
pub const COLLAPSE_BELOW: f64 = 0.6;

/// Collapses `s` toward edges of `seeding`; `locked[i]`: vertex i stays, with its facets.
/// Returns the compacted surface and its lock flags.
pub fn decimate(s: &Surface, locked: &[bool], seeding: f64) -> (Surface, Vec<bool>) {
    let volume = signed_volume(s);
    let rules = CollapseRules {
        size: &|_| seeding,
        max_size: seeding,
        below: COLLAPSE_BELOW,
        above: 1.0,
        pinned: locked,
        absorb_into_pinned: false,
        protected: &|_, _| false,
    };
    let (points, facets, old) = collapse_short_edges(&s.points, &s.facets, &rules);
    let mut out = Surface { points, facets };
    let out_locked: Vec<bool> = old.iter().map(|&v| locked[v as usize]).collect();
    restore_volume(&mut out, &out_locked, volume);
    (out, out_locked)
}

/// Moves the free vertices along their area-weighted normals by the one distance d with
/// V(d) = `volume` to first order (d = ΔV / free area).
fn restore_volume(s: &mut Surface, locked: &[bool], volume: f64) {
    let normals = s.vertex_normals();
    let free_area: f64 = s
        .facets
        .iter()
        .map(|f| {
            let p = f.map(|v| s.points[v as usize]);
            let frees = f.iter().filter(|&&v| !locked[v as usize]).count();
            0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0]))) * frees as f64 / 3.0
        })
        .sum();
    if free_area <= 0.0 {
        return;
    }
    let d = (volume - signed_volume(s)) / free_area;
    for (i, p) in s.points.iter_mut().enumerate() {
        let l = norm(normals[i]);
        if !locked[i] && l > 0.0 {
            *p = add(*p, scale(normals[i], d / l));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::checks::check;
    use crate::sand::icosphere;

    #[test]
    fn a_fine_sphere_coarsens_to_the_seeding_keeping_its_volume_and_locks() {
        let s = icosphere(5); // edges ≈ 0.034
        let locked: Vec<bool> = s.points.iter().map(|p| p[2] > 0.9).collect();
        let before = signed_volume(&s);
        let (d, l) = decimate(&s, &locked, 0.2);
        check(&d).unwrap();
        assert!(
            d.facets.len() < s.facets.len() / 8,
            "{} facets",
            d.facets.len()
        );
        assert!((signed_volume(&d) / before - 1.0).abs() < 1e-3);
        // every locked vertex kept, unmoved
        let kept: Vec<[f64; 3]> = (0..d.points.len())
            .filter(|&i| l[i])
            .map(|i| d.points[i])
            .collect();
        assert_eq!(kept.len(), locked.iter().filter(|&&x| x).count());
        assert!(kept.iter().all(|p| s.points.contains(p)));
        let longest = d
            .facets
            .iter()
            .flat_map(|f| (0..3).map(move |k| (f[k], f[(k + 1) % 3])))
            .map(|(a, b)| norm(sub(d.points[a as usize], d.points[b as usize])))
            .fold(0.0, f64::max);
        assert!(longest <= 0.2 * 1.01, "longest edge {longest}");
    }
}
