//! The physics of one explicit step, and what it needs set up once.
//!
//! - [`stable_step`]: element and contact-spring stable steps, mass scaling;
//! - [`setup`]: a [`Solver`] from a scene (model assembly, time step, overlap check,
//!   initial velocities);
//! - [`step`]: the step pipeline as named, timed stages ([`timing`]): internal forces
//!   ([`forces`]), halo, contact, boundary ([`damping`], [`motions`]), walls, integrate
//!   (`integrate`: the node update in groups of eight lanes), energy; [`diagnose`] names
//!   the element behind a blow-up;
//! - [`periodic`]: the periodic cell in a step (images, homogenised stress, its work);
//! - [`state`]: the one serde [`State`] that evolves; everything else is model or scratch.
//!
//! Nothing here knows about output, partitioning or the command line (that is
//! `crate::driver`); what a step needs from other ranks comes through [`StepHooks`].

mod chunk_order;
pub mod damping;
pub mod diagnose;
mod element_loops;
pub mod element_schedule;
pub mod forces;
mod integrate;
pub mod motions;
pub mod periodic;
pub mod setup;
pub mod stable_step;
pub mod state;
pub mod step;
pub mod timing;

pub use forces::element_response;
pub use setup::{build_solver, build_solver_for, initial_velocities};
pub use state::{RankTotals, Reaction, State};
pub use step::{Scratch, Serial, Solver, StepHooks};
pub use timing::{Stage, StageTimers};
