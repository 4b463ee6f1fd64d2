//! Checks that a triangulated surface bounds one solid — no degenerate facets, manifold
//! edges, closed, consistently and outwardly oriented, one connected part, not
//! self-intersecting — and the safe repairs (`repair = true`): merging near-duplicate
//! vertices, dropping degenerate and duplicate facets, reorienting facets consistently and
//! outward. Each failed check names the first bad facet (lowest index).

use std::collections::HashMap;

use super::intersect::first_self_intersection;
use super::{bounding_box, Surface};
use crate::math::{cross, dot, norm, sub};

/// A defect: the item (`facet 17`) and what is wrong.
pub type Defect = (String, String);

/// Vertices closer than this × the bounding-box diagonal are merged by `repair`.
pub const MERGE_TOLERANCE: f64 = 1e-6;

/// A facet whose area is below this × (its longest edge)² is degenerate (a needle or a
/// sliver with collinear corners).
const DEGENERATE_AREA: f64 = 1e-10;

/// Runs every check in order (degenerate, non-manifold, open, inconsistent orientation,
/// several parts, self-intersection, inward orientation) and returns the first defect.
pub fn check(s: &Surface) -> Result<(), Defect> {
    if let Some((f, why)) = first_degenerate(s) {
        return Err((format!("facet {f}"), format!("degenerate facet ({why})")));
    }
    let edges = edge_groups(s);
    let mut worst: Option<(usize, String, u8)> = None;
    let mut boundary = 0usize;
    for g in &edges {
        let (a, b) = g.vertices;
        let first = g.uses.iter().map(|u| u.0).min().unwrap_or(0);
        let (class, why) = match g.uses.len() {
            1 => {
                boundary += 1;
                (1, format!("not closed: its edge {a}–{b} (vertices) belongs to no other facet"))
            }
            2 if g.uses[0].1 == g.uses[1].1 => (
                2,
                format!(
                    "inconsistent orientation: edge {a}–{b} is traversed in the same direction by facets {} and {}",
                    g.uses[0].0.min(g.uses[1].0),
                    g.uses[0].0.max(g.uses[1].0)
                ),
            ),
            2 => continue,
            n => {
                let list: Vec<String> = g.uses.iter().take(4).map(|u| u.0.to_string()).collect();
                (0, format!("non-manifold edge {a}–{b}: shared by {n} facets ({})", list.join(", ")))
            }
        };
        // Non-manifold before open before orientation; the lowest facet within a class.
        if worst.as_ref().is_none_or(|w| (class, first) < (w.2, w.0)) {
            worst = Some((first, why, class));
        }
    }
    if let Some((f, mut why, class)) = worst {
        if class == 1 {
            why.push_str(&format!(" ({boundary} boundary edges in all)"));
        }
        return Err((format!("facet {f}"), why));
    }
    let parts = connected_parts(s, &edges);
    if let Some(f) = parts.iter().position(|&p| p != 0) {
        let n = parts.iter().max().map_or(1, |m| m + 1);
        return Err((
            format!("facet {f}"),
            format!("the surface has {n} separate closed parts (this facet starts the second); a grain is one closed surface"),
        ));
    }
    if let Some((f, g)) = first_self_intersection(s) {
        return Err((
            format!("facet {f}"),
            format!("self-intersection: crosses facet {g}"),
        ));
    }
    let v = signed_volume(s);
    if v <= 0.0 {
        return Err((
            "facet 0".into(),
            format!(
                "inward orientation: the enclosed signed volume is {} m³ (< 0): facets are ordered clockwise seen from outside",
                crate::error::num(v)
            ),
        ));
    }
    Ok(())
}

/// Signed volume enclosed by the surface (positive when facets are counter-clockwise seen
/// from outside).
pub fn signed_volume(s: &Surface) -> f64 {
    s.facets
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| s.points[i as usize]);
            dot(a, cross(b, c)) / 6.0
        })
        .sum()
}

/// The first degenerate facet and why: a repeated vertex, or (almost) zero area.
fn first_degenerate(s: &Surface) -> Option<(usize, String)> {
    s.facets
        .iter()
        .enumerate()
        .find_map(|(i, f)| degeneracy(s, f).map(|w| (i, w)))
}

fn degeneracy(s: &Surface, f: &[u32; 3]) -> Option<String> {
    if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
        return Some(format!("repeated vertex: {} {} {}", f[0], f[1], f[2]));
    }
    let [a, b, c] = f.map(|i| s.points[i as usize]);
    let longest = [norm(sub(b, a)), norm(sub(c, b)), norm(sub(a, c))]
        .into_iter()
        .fold(0.0, f64::max);
    let area = 0.5 * norm(cross(sub(b, a), sub(c, a)));
    (area <= DEGENERATE_AREA * longest * longest).then(|| {
        format!(
            "zero area: vertices {} {} {} are collinear or coincide",
            f[0], f[1], f[2]
        )
    })
}

/// An undirected edge and the facets using it: (facet, runs from the lower to the higher id).
pub(crate) struct EdgeGroup {
    pub vertices: (u32, u32),
    pub uses: Vec<(usize, bool)>,
}

/// Every undirected edge with its facets, by sorting the 3n directed edges (no hashing).
pub(crate) fn edge_groups(s: &Surface) -> Vec<EdgeGroup> {
    let mut all: Vec<(u64, usize, bool)> = Vec::with_capacity(3 * s.facets.len());
    for (fi, f) in s.facets.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
            all.push((key, fi, a < b));
        }
    }
    all.sort_unstable();
    let mut groups: Vec<EdgeGroup> = Vec::new();
    for (key, fi, up) in all {
        match groups.last_mut() {
            Some(g) if ((g.vertices.0 as u64) << 32 | g.vertices.1 as u64) == key => {
                g.uses.push((fi, up))
            }
            _ => groups.push(EdgeGroup {
                vertices: ((key >> 32) as u32, key as u32),
                uses: vec![(fi, up)],
            }),
        }
    }
    groups
}

/// Part number of each facet (parts numbered by their lowest facet), over edges shared by
/// exactly two facets.
fn connected_parts(s: &Surface, edges: &[EdgeGroup]) -> Vec<usize> {
    let n = s.facets.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for g in edges.iter().filter(|g| g.uses.len() == 2) {
        let (a, b) = (
            root(&mut parent, g.uses[0].0),
            root(&mut parent, g.uses[1].0),
        );
        let (lo, hi) = (a.min(b), a.max(b));
        parent[hi] = lo;
    }
    let mut number: HashMap<usize, usize> = HashMap::new();
    (0..n)
        .map(|i| {
            let r = root(&mut parent, i);
            let next = number.len();
            *number.entry(r).or_insert(next)
        })
        .collect()
}

/// What [`repair`] changed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Repairs {
    pub merged_vertices: usize,
    pub dropped_degenerate: usize,
    pub dropped_duplicates: usize,
    pub flipped: usize,
}

impl Repairs {
    pub fn is_empty(&self) -> bool {
        *self == Repairs::default()
    }
}

impl std::fmt::Display for Repairs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "merged {} duplicate vertices (within {MERGE_TOLERANCE:e} × the bounding-box diagonal), dropped {} degenerate and {} duplicate facets, flipped {} facets",
            self.merged_vertices, self.dropped_degenerate, self.dropped_duplicates, self.flipped
        )
    }
}

/// Repairs what is safely repairable, in place: merges vertices closer than
/// [`MERGE_TOLERANCE`] × the bounding-box diagonal (to the first of them), drops facets
/// that become degenerate and repeated facets, and orients every connected part
/// consistently (breadth-first over manifold edges) and outward (positive volume).
/// Other defects stay for [`check`] to report.
pub fn repair(s: &mut Surface) -> Repairs {
    let mut r = Repairs {
        merged_vertices: merge_close_vertices(s),
        ..Repairs::default()
    };
    let before = s.facets.len();
    let snapshot = s.clone();
    s.facets.retain(|f| degeneracy(&snapshot, f).is_none());
    r.dropped_degenerate = before - s.facets.len();
    let mut seen = std::collections::HashSet::new();
    let before = s.facets.len();
    s.facets.retain(|f| {
        let mut k = *f;
        k.sort_unstable();
        seen.insert(k)
    });
    r.dropped_duplicates = before - s.facets.len();
    r.flipped = orient(s);
    r
}

fn merge_close_vertices(s: &mut Surface) -> usize {
    let (lo, hi) = bounding_box(&s.points);
    let tol = MERGE_TOLERANCE * norm(sub(hi, lo));
    if tol <= 0.0 {
        return 0;
    }
    let cell = |p: [f64; 3]| p.map(|c| (c / tol).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut target: Vec<u32> = Vec::with_capacity(s.points.len());
    let mut merged = 0;
    for (i, &p) in s.points.iter().enumerate() {
        let c = cell(p);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        if let Some(&j) = list
                            .iter()
                            .find(|&&j| norm(sub(s.points[j as usize], p)) <= tol)
                        {
                            found = Some(j);
                            break 'search;
                        }
                    }
                }
            }
        }
        match found {
            Some(j) => {
                target.push(j);
                merged += 1;
            }
            None => {
                target.push(i as u32);
                grid.entry(c).or_default().push(i as u32);
            }
        }
    }
    for f in s.facets.iter_mut() {
        *f = f.map(|i| target[i as usize]);
    }
    merged
}

/// Orients each part consistently with its lowest facet, then flips parts of negative
/// volume; returns how many facets changed.
fn orient(s: &mut Surface) -> usize {
    let original = s.facets.clone();
    let edges = edge_groups(s);
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); s.facets.len()];
    for g in edges.iter().filter(|g| g.uses.len() == 2) {
        neighbours[g.uses[0].0].push(g.uses[1].0);
        neighbours[g.uses[1].0].push(g.uses[0].0);
    }
    let mut done = vec![false; s.facets.len()];
    for start in 0..s.facets.len() {
        if done[start] {
            continue;
        }
        done[start] = true;
        let mut part = vec![start];
        let mut k = 0;
        while k < part.len() {
            let f = part[k];
            k += 1;
            for &g in &neighbours[f] {
                if done[g] {
                    continue;
                }
                done[g] = true;
                // Consistent: the shared edge runs in opposite directions in f and g.
                if shares_directed_edge(&s.facets[f], &s.facets[g]) {
                    s.facets[g].swap(1, 2);
                }
                part.push(g);
            }
        }
        let part_surface = Surface {
            points: s.points.clone(),
            facets: part.iter().map(|&f| s.facets[f]).collect(),
        };
        if signed_volume(&part_surface) < 0.0 {
            for &f in &part {
                s.facets[f].swap(1, 2);
            }
        }
    }
    s.facets
        .iter()
        .zip(&original)
        .filter(|(a, b)| a != b)
        .count()
}

fn shares_directed_edge(f: &[u32; 3], g: &[u32; 3]) -> bool {
    (0..3).any(|i| (0..3).any(|j| f[i] == g[j] && f[(i + 1) % 3] == g[(j + 1) % 3]))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::mesh::import::formats::surface_from_soup;

    pub(crate) fn cube() -> Surface {
        // Unit cube, 12 outward triangles.
        let v = |i: usize| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64];
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        surface_from_soup(
            quads
                .iter()
                .flat_map(|q| [[v(q[0]), v(q[1]), v(q[2])], [v(q[0]), v(q[2]), v(q[3])]]),
        )
    }

    #[test]
    fn a_cube_passes_and_each_defect_is_named() {
        let c = cube();
        check(&c).unwrap();
        assert!((signed_volume(&c) - 1.0).abs() < 1e-12);

        let mut open = c.clone();
        open.facets.remove(3);
        let e = check(&open).unwrap_err();
        assert!(e.1.starts_with("not closed"), "{e:?}");

        let mut flipped = c.clone();
        flipped.facets[5].swap(1, 2);
        let e = check(&flipped).unwrap_err();
        assert!(
            e.1.starts_with("inconsistent orientation") && e.1.contains(" and 5"),
            "{e:?}"
        );

        let mut inward = c.clone();
        inward.facets.iter_mut().for_each(|f| f.swap(1, 2));
        assert!(check(&inward)
            .unwrap_err()
            .1
            .starts_with("inward orientation"));

        let mut degenerate = c.clone();
        degenerate.facets[7] = [1, 1, 2];
        assert_eq!(check(&degenerate).unwrap_err().0, "facet 7");

        let mut nonmanifold = c.clone();
        nonmanifold.facets.push(c.facets[2]);
        nonmanifold.facets[12].swap(1, 2);
        assert!(check(&nonmanifold)
            .unwrap_err()
            .1
            .starts_with("non-manifold edge"));

        let mut two = c.clone();
        let n = two.points.len() as u32;
        two.points
            .extend(c.points.iter().map(|p| p.map(|x| x + 5.0)));
        two.facets.extend(c.facets.iter().map(|f| f.map(|i| i + n)));
        assert_eq!(check(&two).unwrap_err().0, "facet 12");
    }

    #[test]
    fn repair_merges_near_duplicates_and_reorients() {
        let mut s = cube();
        // Split vertex 0 into a near-duplicate for facet 0 and flip facets 3 and 8.
        s.points.push([1e-9, 0.0, 0.0]);
        let n = (s.points.len() - 1) as u32;
        s.facets[0][0] = n;
        s.facets[3].swap(1, 2);
        s.facets[8].swap(1, 2);
        assert!(check(&s).is_err());
        let r = repair(&mut s);
        assert_eq!((r.merged_vertices, r.flipped), (1, 2), "{r}");
        check(&s).unwrap();
        let mut inward = cube();
        inward.facets.iter_mut().for_each(|f| f.swap(1, 2));
        assert_eq!(repair(&mut inward).flipped, 12);
        check(&inward).unwrap();
    }
}
