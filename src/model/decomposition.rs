//! Which grains a rank owns, which it mirrors as ghosts, and what it exchanges with whom.
//! Pure bookkeeping (no MPI): every rank evaluates the same rules on the same global data
//! (grain bounding spheres gathered from all ranks), so the plans of two ranks always
//! match without negotiation.

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
    /// Global ids of other ranks' grains mirrored here (surface only), ascending.
    pub ghosts: Vec<usize>,
    /// For each neighbour rank (ascending): owned grains whose surfaces it mirrors, ascending.
    pub sends: Vec<(usize, Vec<usize>)>,
    /// For each neighbour rank (ascending): its grains mirrored here, ascending.
    pub receives: Vec<(usize, Vec<usize>)>,
}

impl Decomposition {
    /// Builds the plan of `rank` from the global owner table and grain bounds. A grain g
    /// owned by q ≠ r is a ghost on r iff some grain owned by r is near g; q evaluates the
    /// same predicate to decide what to send, so both sides agree.
    pub fn plan(owner: &[u32], bounds: &[GrainBound], margin: f64, rank: usize) -> Self {
        let n = owner.len();
        let ranks = owner.iter().map(|&r| r as usize + 1).max().unwrap_or(1);
        // grains per rank, for the neighbour test
        let mut by_rank: Vec<Vec<usize>> = vec![Vec::new(); ranks];
        for (g, &r) in owner.iter().enumerate() {
            by_rank[r as usize].push(g);
        }
        let near_rank = |g: usize, r: usize| {
            by_rank[r]
                .iter()
                .any(|&h| bounds[h].near(&bounds[g], margin))
        };
        let owned = by_rank.get(rank).cloned().unwrap_or_default();
        let ghosts: Vec<usize> = (0..n)
            .filter(|&g| owner[g] as usize != rank && near_rank(g, rank))
            .collect();
        let mut sends = Vec::new();
        let mut receives = Vec::new();
        for q in 0..ranks {
            if q == rank {
                continue;
            }
            let s: Vec<usize> = owned.iter().copied().filter(|&g| near_rank(g, q)).collect();
            if !s.is_empty() {
                sends.push((q, s));
            }
            let r: Vec<usize> = ghosts
                .iter()
                .copied()
                .filter(|&g| owner[g] as usize == q)
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
        let p0 = Decomposition::plan(&owner, &bounds, 0.1, 0);
        let p1 = Decomposition::plan(&owner, &bounds, 0.1, 1);
        assert_eq!(p0.owned, vec![0, 1, 2]);
        assert_eq!(p0.ghosts, vec![3]);
        assert_eq!(p1.ghosts, vec![2]);
        assert_eq!(p0.sends, vec![(1, vec![2])]);
        assert_eq!(p1.receives, vec![(0, vec![2])]);
        assert_eq!(p1.sends, vec![(0, vec![3])]);
        assert_eq!(p0.receives, vec![(1, vec![3])]);
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
            .map(|r| Decomposition::plan(&owner, &bounds, 0.05, r))
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
