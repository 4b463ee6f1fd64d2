//! mufe — micro finite-element (μFE) simulator for granular soil.
//!
//! Every grain is a deformable linear-tetrahedral mesh; grains interact only through
//! their meshed surfaces; time integration is explicit central difference. The crate is
//! laid out in layers that depend one way, downwards (see `docs/ARCHITECTURE.md`):
//!
//! - `cli` → `driver` (a run as phases: partition, build, loop, output) and `validate`;
//! - `solver` (one explicit step) → `contact` → `model` (the static layout of a rank);
//! - `io` (results file, plots), `domain` (the only module that talks to MPI);
//! - `model` → `boundary`, `element`, `material`, `mesh`, `scene`, `energy`, `math`.

// Component loops `for i in 0..3` over small fixed-size vectors and tensors read as the
// index notation of the formulas they implement; iterator rewrites obscure that.
#![allow(clippy::needless_range_loop)]

pub mod error;
pub mod mesh;
pub mod model;

/// Scalar type used throughout (SI units).
pub type Real = f64;
/// 3-vector (m, m/s, N, ... depending on context).
pub type Vec3 = nalgebra::Vector3<Real>;
/// 3×3 matrix (deformation gradients, stresses in Pa).
pub type Mat3 = nalgebra::Matrix3<Real>;
pub mod boundary;
pub mod cli;
pub mod contact;
pub mod domain;
pub mod driver;
pub mod element;
pub mod energy;
pub mod image;
pub mod io;
pub mod kinematics;
pub mod lanes;
pub mod material;
pub mod math;
pub mod packed_vectors;
pub mod sand;
pub mod scene;
pub mod solver;
#[cfg(test)]
pub(crate) mod testing;
pub mod validate;
