//! Regular test packings of equal spheres.

/// Largest allowed ratio of the longest to the shortest block edge (in unit
/// cells) for [`fcc_packing`]; keeps blocks compact instead of degenerating to
/// a 1 × 1 × n column when the cell count is prime.
pub const MAX_FCC_BLOCK_ASPECT: usize = 4;

/// Largest grain count [`fcc_packing`] generates (2^28 ≈ 268 M grains,
/// 6.4 GB of centres); larger targets are clamped to it.
pub const MAX_FCC_GRAINS: usize = 1 << 28;

/// Fractional positions of the 4 lattice points of the FCC conventional
/// (cubic) unit cell.
const FCC_BASIS: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [0.5, 0.5, 0.0],
    [0.5, 0.0, 0.5],
    [0.0, 0.5, 0.5],
];

/// Unit cells `[nx, ny, nz]` of the block [`fcc_packing`] builds for
/// `n_target` grains, or `None` if fewer than 4 grains are requested.
///
/// Uses the largest cell count `c ≤ n_target / 4` that factors as
/// `nx · ny · nz` with `nx ≤ ny ≤ nz ≤ MAX_FCC_BLOCK_ASPECT · nx`, choosing
/// the most cube-like factorisation (smallest `nz / nx`, then smallest `nz`).
/// Example: 2000 grains = 500 cells = 5 × 10 × 10.
pub fn fcc_block_cells(n_target: usize) -> Option<[usize; 3]> {
    let max_cells = n_target.min(MAX_FCC_GRAINS) / FCC_BASIS.len();
    (1..=max_cells).rev().find_map(most_compact_block)
}

/// Most cube-like `[nx, ny, nz]` with `nx ≤ ny ≤ nz`, product `cells` and
/// aspect within [`MAX_FCC_BLOCK_ASPECT`], if any.
fn most_compact_block(cells: usize) -> Option<[usize; 3]> {
    let mut best: Option<[usize; 3]> = None;
    let mut nx = 1;
    while nx * nx * nx <= cells {
        if cells.is_multiple_of(nx) {
            let rest = cells / nx;
            let mut ny = nx;
            while ny * ny <= rest {
                if rest.is_multiple_of(ny) {
                    let candidate = [nx, ny, rest / ny];
                    let better = match best {
                        None => true,
                        // Compare nz/nx by cross-multiplication (exact), then nz.
                        Some(b) => {
                            let (lhs, rhs) = (candidate[2] * b[0], b[2] * candidate[0]);
                            lhs < rhs || (lhs == rhs && candidate[2] < b[2])
                        }
                    };
                    if better {
                        best = Some(candidate);
                    }
                }
                ny += 1;
            }
        }
        nx += 1;
    }
    best.filter(|b| b[2] <= MAX_FCC_BLOCK_ASPECT * b[0])
}

/// Centres (m) of a face-centred cubic packing of touching spheres of radius
/// `radius` (m): nearest-neighbour distance `2·radius`, cubic lattice constant
/// `a = 2√2·radius`, cube axes along x, y, z (z is the `[001]` direction).
///
/// The block is `[nx, ny, nz]` = [`fcc_block_cells`]`(n_target)` unit cells of
/// 4 grains each, longest edge along z, so it holds exactly `n_target` grains
/// when `n_target` is a multiple of 4 with a compact block shape (e.g.
/// `fcc_packing(2000, r)` = 5 × 10 × 10 cells), otherwise the nearest count
/// below that has one. Only the 4 sites of each cell's conventional basis are
/// used, so the +x/+y/+z faces are not closed with extra sites.
///
/// Centres are ordered z-major (cell z, then y, then x, then basis site) and
/// shifted so every sphere lies in the positive octant, touching the planes
/// x = 0, y = 0 and z = 0.
///
/// Returns an empty vector if `n_target < 4` or `radius` is not a positive
/// finite number small enough for the block to have finite coordinates.
pub fn fcc_packing(n_target: usize, radius: f64) -> Vec<[f64; 3]> {
    let Some(cells) = fcc_block_cells(n_target) else {
        return Vec::new();
    };
    let lattice_constant = 2.0 * std::f64::consts::SQRT_2 * radius;
    let largest = lattice_constant * (cells[2] as f64 + 1.0) + radius;
    if !(radius > 0.0 && largest.is_finite()) {
        return Vec::new();
    }

    let mut centres = Vec::with_capacity(cells.iter().product::<usize>() * FCC_BASIS.len());
    for iz in 0..cells[2] {
        for iy in 0..cells[1] {
            for ix in 0..cells[0] {
                for site in &FCC_BASIS {
                    let cell = [ix, iy, iz];
                    centres.push(std::array::from_fn(|k| {
                        (cell[k] as f64 + site[k]) * lattice_constant + radius
                    }));
                }
            }
        }
    }
    centres
}

#[cfg(test)]
mod tests {
    use super::*;

    fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
        (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
    }

    #[test]
    fn two_thousand_grains_exactly() {
        assert_eq!(fcc_block_cells(2000), Some([5, 10, 10]));
        assert_eq!(fcc_packing(2000, 1.1e-3).len(), 2000);
    }

    #[test]
    fn nearest_neighbour_distance_is_two_radii() {
        let radius = 1.1e-3;
        let centres = fcc_packing(256, radius);
        assert_eq!(centres.len(), 256);
        for (i, a) in centres.iter().enumerate() {
            let nearest = centres
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, b)| distance(a, b))
                .fold(f64::INFINITY, f64::min);
            assert!(
                (nearest - 2.0 * radius).abs() < 1e-12 * radius.max(1.0),
                "grain {i}: nearest neighbour at {nearest}, expected {}",
                2.0 * radius
            );
        }
        // All spheres in the positive octant, touching the coordinate planes.
        for k in 0..3 {
            let min = centres.iter().map(|c| c[k]).fold(f64::INFINITY, f64::min);
            assert!((min - radius).abs() < 1e-15);
        }
    }

    #[test]
    fn counts_round_down_to_compact_blocks() {
        // Multiples of 4 with a compact shape are exact.
        for n in [4, 32, 108, 256, 500, 864, 4000, 32_000] {
            assert_eq!(fcc_packing(n, 1.0).len(), n, "n = {n}");
        }
        // Not a multiple of 4: nearest multiple below.
        assert_eq!(fcc_packing(2003, 1.0).len(), 2000);
        // 4·101 (101 prime) has no compact block: 100 cells = 4 × 5 × 5 instead.
        assert_eq!(fcc_block_cells(404), Some([4, 5, 5]));
        assert_eq!(fcc_packing(404, 1.0).len(), 400);
        for n in [5, 17, 999, 12_345] {
            let cells = fcc_block_cells(n).unwrap();
            assert!(cells[0] <= cells[1] && cells[1] <= cells[2]);
            assert!(cells[2] <= MAX_FCC_BLOCK_ASPECT * cells[0]);
            assert!(4 * cells.iter().product::<usize>() <= n);
        }
    }

    #[test]
    fn bad_input_gives_empty_packing() {
        assert!(fcc_packing(3, 1.0).is_empty());
        assert!(fcc_packing(0, 1.0).is_empty());
        assert!(fcc_packing(100, 0.0).is_empty());
        assert!(fcc_packing(100, -1.0).is_empty());
        assert!(fcc_packing(100, f64::NAN).is_empty());
        assert!(fcc_packing(100, f64::INFINITY).is_empty());
        assert!(fcc_packing(100, 1e308).is_empty());
    }
}
