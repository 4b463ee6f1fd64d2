//! Which grains a rank owns, which it mirrors as ghosts, and what it exchanges with whom.
//! Pure bookkeeping (no MPI): every rank evaluates the same rules on the same global data
//! (grain bounding spheres gathered from all ranks), so the plans of two ranks always
//! match without negotiation.

use super::periodic::{Image, PeriodicCell, NO_IMAGE};

/// Current bounding sphere of a grain (m).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GrainBound {
    pub centre: [f64; 3],
    pub radius: f64,
}

impl GrainBound {
    /// True when the two grains can touch within `margin`.
    pub fn near(&self, other: &GrainBound, margin: f64) -> bool {
        let d2 = (0..3)
            .map(|i| (self.centre[i] - other.centre[i]).powi(2))
            .sum::<f64>();
        let reach = self.radius + other.radius + margin;
        d2 <= reach * reach
    }
}

/// The partition of the grains over the ranks as it evolves (part of the run's state, the
/// same on every rank): the owner of every grain, and every grain's bounding sphere when
/// the ghosts were last planned (the ghost plan is renewed once some grain has moved
/// far enough from it).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Partition {
    /// Owning rank of every grain (global id order).
    pub owner: Vec<u32>,
    /// Bounding spheres at the last ghost plan.
    pub planned_bounds: Vec<GrainBound>,
    /// Edge lengths of the periodic cell at the last ghost plan (m; zero without one).
    #[serde(default)]
    pub planned_cell: [f64; 3],
}

/// A grain mirrored on a rank: the grain itself (another rank's) or one of its periodic
/// images (`image` ≠ 0; its own grains' images too). Ordered by (grain, image).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct GhostRef {
    pub grain: usize,
    pub image: Image,
}

/// One rank's share of the grains and its halo pattern.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Decomposition {
    /// Owning rank of every grain (global).
    pub owner: Vec<u32>,
    /// This rank.
    pub rank: usize,
    /// Global ids of the grains this rank owns, ascending.
    pub owned: Vec<usize>,
    /// Grains and images mirrored here (surface only), ascending: other ranks' grains
    /// near an owned one, and periodic images near an owned one.
    pub ghosts: Vec<GhostRef>,
    /// For each neighbour rank (ascending): owned grains (and images) whose surfaces it
    /// mirrors, ascending. An image of an owned grain mirrored here is copied locally.
    pub sends: Vec<(usize, Vec<GhostRef>)>,
    /// For each neighbour rank (ascending): its grains (and images) mirrored here.
    pub receives: Vec<(usize, Vec<GhostRef>)>,
}

/// The periodic cell when the ghosts are planned: its layout and current edge lengths.
#[derive(Debug, Clone, Copy)]
pub struct PlanCell<'a> {
    pub cell: &'a PeriodicCell,
    pub length: [f64; 3],
}

impl Decomposition {
    /// Builds the plan of `rank` from the global owner table and grain bounds. Grain g
    /// (or its image s) is a ghost on r iff some grain owned by r is near it (not g
    /// itself unshifted); its owner evaluates the same predicate to decide what to send,
    /// so both sides agree.
    pub fn plan(
        owner: &[u32],
        bounds: &[GrainBound],
        margin: f64,
        rank: usize,
        cell: Option<PlanCell>,
    ) -> Self {
        let n = owner.len();
        let ranks = owner.iter().map(|&r| r as usize + 1).max().unwrap_or(1);
        // grains per rank, for the neighbour test
        let mut by_rank: Vec<Vec<usize>> = vec![Vec::new(); ranks];
        for (g, &r) in owner.iter().enumerate() {
            by_rank[r as usize].push(g);
        }
        let images = cell.map_or_else(|| vec![NO_IMAGE], |c| c.cell.images());
        let reach = 2.0 * bounds.iter().map(|b| b.radius).fold(0.0, f64::max) + margin;
        // an image can touch anything only when its grain lies within reach of the face
        // the shift carries it across
        let relevant = |g: usize, s: Image| {
            let Some(c) = cell else {
                return s == NO_IMAGE;
            };
            (0..3).all(|k| match s[k] {
                1 => bounds[g].centre[k] - c.cell.min[k] < reach,
                -1 => c.cell.min[k] + c.length[k] - bounds[g].centre[k] < reach,
                _ => true,
            })
        };
        let shifted = |g: usize, s: Image| {
            let mut b = bounds[g];
            if let Some(c) = cell {
                for k in 0..3 {
                    b.centre[k] += f64::from(s[k]) * c.length[k];
                }
            }
            b
        };
        let near_rank = |g: usize, s: Image, r: usize| {
            let b = shifted(g, s);
            by_rank[r]
                .iter()
                .any(|&h| (h != g || s != NO_IMAGE) && bounds[h].near(&b, margin))
        };
        let owned = by_rank.get(rank).cloned().unwrap_or_default();
        let mut ghosts = Vec::new();
        for g in 0..n {
            for &s in &images {
                let other = owner[g] as usize != rank || s != NO_IMAGE;
                if other && relevant(g, s) && near_rank(g, s, rank) {
                    ghosts.push(GhostRef { grain: g, image: s });
                }
            }
        }
        ghosts.sort_unstable();
        let mut sends = Vec::new();
        let mut receives = Vec::new();
        for q in 0..ranks {
            if q == rank {
                continue;
            }
            let mut s: Vec<GhostRef> = owned
                .iter()
                .flat_map(|&g| images.iter().map(move |&i| GhostRef { grain: g, image: i }))
                .filter(|r| relevant(r.grain, r.image) && near_rank(r.grain, r.image, q))
                .collect();
            s.sort_unstable();
            if !s.is_empty() {
                sends.push((q, s));
            }
            let r: Vec<GhostRef> = ghosts
                .iter()
                .copied()
                .filter(|r| owner[r.grain] as usize == q)
                .collect();
            if !r.is_empty() {
                receives.push((q, r));
            }
        }
        Self {
            owner: owner.to_vec(),
            rank,
            owned,
            ghosts,
            sends,
            receives,
        }
    }

    /// Whether grain `g` is held here (owned, mirrored, or as an image).
    pub fn holds(&self, g: usize) -> bool {
        self.owned.binary_search(&g).is_ok() || self.ghosts.iter().any(|r| r.grain == g)
    }
}

/// How far beyond ½ ghost margin outside a receiving grain's bounding sphere a ghost's
/// surface node is still sent every step (m), for a node whose facets within two rings
/// have longest edge `longest_edge` and a receiving side whose broad-phase query boxes
/// reach `query_half_size` (margin + ½ h) from its nodes: a facet's box lies within
/// 1.58 e of each corner (the box of its smallest enclosing ball), a curved patch reads one
/// ring beyond its corners, and a query box reaches √3 × its half-size. See
/// `crate::domain::halo` for why this keeps the results of whole ghosts.
pub fn contact_zone_cushion(longest_edge: f64, query_half_size: f64) -> f64 {
    2.6 * longest_edge + 3f64.sqrt() * query_half_size
}

/// The contact zone of ghost `grain` on rank `receiver`: (centre, R + ½ `margin`) of the
/// receiver's grains whose bounding spheres come within ½ `margin` + `widest_cushion` of
/// the ghost's (`bounds`, `owner` global).
pub fn contact_zone(
    owner: &[u32],
    bounds: &[GrainBound],
    margin: f64,
    grain: usize,
    receiver: usize,
    widest_cushion: f64,
) -> Vec<([f64; 3], f64)> {
    let b = bounds[grain];
    (0..bounds.len())
        .filter(|&h| owner[h] as usize == receiver && h != grain)
        .filter(|&h| bounds[h].near(&b, 0.5 * margin + widest_cushion))
        .map(|h| (bounds[h].centre, bounds[h].radius + 0.5 * margin))
        .collect()
}

/// Whether a node at `p` with cushion `cushion` (m) lies in `zone`
/// ([`contact_zone`], [`contact_zone_cushion`]).
pub fn in_contact_zone(zone: &[([f64; 3], f64)], p: [f64; 3], cushion: f64) -> bool {
    zone.iter().any(|(c, r)| {
        let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() <= r + cushion
    })
}

/// Load imbalance max/mean − 1 of per-rank costs.
pub fn imbalance(costs: &[f64]) -> f64 {
    let mean = costs.iter().sum::<f64>() / costs.len().max(1) as f64;
    if mean <= 0.0 {
        0.0
    } else {
        costs.iter().cloned().fold(0.0, f64::max) / mean - 1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(n: usize) -> Vec<GrainBound> {
        (0..n)
            .map(|i| GrainBound {
                centre: [2.0 * i as f64, 0.0, 0.0],
                radius: 1.0,
            })
            .collect()
    }

    #[test]
    fn plans_of_two_ranks_match() {
        let bounds = row(6);
        let owner = [0, 0, 0, 1, 1, 1];
        let p0 = Decomposition::plan(&owner, &bounds, 0.1, 0, None);
        let p1 = Decomposition::plan(&owner, &bounds, 0.1, 1, None);
        assert_eq!(p0.owned, vec![0, 1, 2]);
        assert_eq!(p0.ghosts, vec![real(3)]);
        assert_eq!(p1.ghosts, vec![real(2)]);
        assert_eq!(p0.sends, vec![(1, vec![real(2)])]);
        assert_eq!(p1.receives, vec![(0, vec![real(2)])]);
        assert_eq!(p1.sends, vec![(0, vec![real(3)])]);
        assert_eq!(p0.receives, vec![(1, vec![real(3)])]);
    }

    fn real(grain: usize) -> GhostRef {
        GhostRef {
            grain,
            image: NO_IMAGE,
        }
    }

    #[test]
    fn a_periodic_row_mirrors_the_images_across_the_box() {
        // six grains 2 apart in a box of length 12 along x: the last touches the first's
        // image and the first the last's
        let bounds = row(6);
        let cell = PeriodicCell {
            periodic: [true, false, false],
            min: [-1.0, -1.0, -1.0],
            length0: [12.0, 2.0, 2.0],
        };
        let at = Some(PlanCell {
            cell: &cell,
            length: cell.length0,
        });
        let image = |grain: usize, x: i8| GhostRef {
            grain,
            image: [x, 0, 0],
        };
        let serial = Decomposition::plan(&[0; 6], &bounds, 0.1, 0, at);
        assert_eq!(serial.ghosts, vec![image(0, 1), image(5, -1)]);
        assert!(serial.sends.is_empty() && serial.receives.is_empty());
        let owner = [0, 0, 0, 1, 1, 1];
        let p0 = Decomposition::plan(&owner, &bounds, 0.1, 0, at);
        let p1 = Decomposition::plan(&owner, &bounds, 0.1, 1, at);
        assert_eq!(p0.ghosts, vec![real(3), image(5, -1)]);
        assert_eq!(p1.ghosts, vec![image(0, 1), real(2)]);
        assert_eq!(p0.sends, vec![(1, vec![image(0, 1), real(2)])]);
        assert_eq!(
            p1.receives,
            p0.sends
                .iter()
                .map(|(_, g)| (0, g.clone()))
                .collect::<Vec<_>>()
        );
        assert_eq!(p1.sends, vec![(0, vec![real(3), image(5, -1)])]);
        assert_eq!(p0.receives, vec![(1, vec![real(3), image(5, -1)])]);
        // the cell shortened by half a spacing: still the same neighbours, nothing more
        let shorter = Some(PlanCell {
            cell: &cell,
            length: [11.0, 2.0, 2.0],
        });
        assert_eq!(
            Decomposition::plan(&[0; 6], &bounds, 0.1, 0, shorter).ghosts,
            serial.ghosts
        );
    }

    #[test]
    fn every_send_has_a_matching_receive_for_three_ranks() {
        let bounds: Vec<GrainBound> = (0..27)
            .map(|i| GrainBound {
                centre: [
                    2.0 * (i % 3) as f64,
                    2.0 * ((i / 3) % 3) as f64,
                    2.0 * (i / 9) as f64,
                ],
                radius: 1.0,
            })
            .collect();
        let owner: Vec<u32> = (0..27).map(|i| ((i * 7) % 3) as u32).collect();
        let plans: Vec<Decomposition> = (0..3)
            .map(|r| Decomposition::plan(&owner, &bounds, 0.05, r, None))
            .collect();
        for p in &plans {
            for (q, grains) in &p.sends {
                let back = plans[*q]
                    .receives
                    .iter()
                    .find(|(r, _)| *r == p.rank)
                    .expect("matching receive");
                assert_eq!(&back.1, grains);
            }
        }
        assert!((imbalance(&[1.0, 1.0, 1.0])).abs() < 1e-15);
        assert!((imbalance(&[2.0, 1.0, 0.0]) - 1.0).abs() < 1e-15);
    }
}
