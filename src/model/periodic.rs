//! The static layout of a periodic cell: which axes repeat, the box at t = 0, and the
//! image shifts of grains. The box's current edge lengths are run state (the stages move
//! them, `crate::solver::periodic`); an image of grain g with shift s sits at
//! x + Σₖ sₖ Lₖ(t) eₖ and moves with v + Σₖ sₖ L̇ₖ eₖ.

use crate::scene::cell::PeriodicBox;

/// Image shift of a grain in cell lengths along x, y, z (each −1, 0 or 1: grains stay
/// inside the box, so a neighbour is at most one period away).
pub type Image = [i8; 3];

/// The shift of the grain itself.
pub const NO_IMAGE: Image = [0; 3];

/// The periodic cell of a scene (identical on every rank): the scene's box, with the
/// image shifts and wrapping below.
pub type PeriodicCell = PeriodicBox;

/// Edge lengths and their rates at one instant (m, m/s); all zero without a cell.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CellKinematics {
    pub length: [f64; 3],
    pub rate: [f64; 3],
}

impl CellKinematics {
    /// Offset of image `s` (m).
    #[inline]
    pub fn offset(&self, s: Image) -> [f64; 3] {
        [0, 1, 2].map(|k| f64::from(s[k]) * self.length[k])
    }

    /// Velocity of image `s` relative to its grain (m/s).
    #[inline]
    pub fn velocity(&self, s: Image) -> [f64; 3] {
        [0, 1, 2].map(|k| f64::from(s[k]) * self.rate[k])
    }
}

impl PeriodicCell {
    /// Every image shift of the cell, the grain itself (all zero) first, then ascending:
    /// ±1 along periodic axes only.
    pub fn images(&self) -> Vec<Image> {
        let range = |k: usize| if self.periodic[k] { -1..=1 } else { 0..=0 };
        let mut out = vec![NO_IMAGE];
        for a in range(0) {
            for b in range(1) {
                for c in range(2) {
                    let s = [a, b, c];
                    if s != NO_IMAGE {
                        out.push(s);
                    }
                }
            }
        }
        out
    }

    /// Kinematics at t = 0.
    pub fn at_rest(&self) -> CellKinematics {
        CellKinematics {
            length: self.length0,
            rate: [0.0; 3],
        }
    }

    /// The cell vector that brings a point at `p` back into the box [min, min + L) along
    /// every periodic axis (m; zero when it is inside).
    pub fn wrap_offset(&self, p: [f64; 3], length: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|k| {
            if !self.periodic[k] || length[k] <= 0.0 {
                return 0.0;
            }
            let periods = ((p[k] - self.min[k]) / length[k]).floor();
            -periods * length[k]
        })
    }
}

/// The relative image of `master` seen from `slave` (`master − slave`).
#[inline]
pub fn relative_image(slave: Image, master: Image) -> Image {
    [0, 1, 2].map(|k| master[k] - slave[k])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_cover_the_periodic_axes_only_with_the_grain_first() {
        let cell = PeriodicCell {
            periodic: [true, false, true],
            min: [0.0; 3],
            length0: [1.0; 3],
        };
        let images = cell.images();
        assert_eq!(images.len(), 9);
        assert_eq!(images[0], NO_IMAGE);
        assert!(images.iter().all(|s| s[1] == 0));
        let k = CellKinematics {
            length: [2.0, 3.0, 4.0],
            rate: [-1.0, 0.0, 0.5],
        };
        assert_eq!(k.offset([1, 0, -1]), [2.0, 0.0, -4.0]);
        assert_eq!(k.velocity([1, 0, -1]), [-1.0, 0.0, -0.5]);
        assert_eq!(
            cell.wrap_offset([2.5, 7.0, -0.5], [2.0, 3.0, 4.0]),
            [-2.0, 0.0, 4.0]
        );
        assert_eq!(cell.wrap_offset([0.5, 0.5, 0.5], [2.0, 3.0, 4.0]), [0.0; 3]);
    }
}
