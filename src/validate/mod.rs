//! Analytic validation cases (`mufe validate`): the contact laws of THEORY.md must emerge
//! from the mesh. Each case is a scene in `jobs/validation/`, run at a list of meshing
//! ratios; the documented error metric compares the FE curve with the reference over the
//! whole loading range.

pub mod plot;
pub mod reference;
pub mod hertz;
pub mod runner;
