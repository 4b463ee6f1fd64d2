//! Stable Δt, mass scaling, damping, central-difference integration: the step pipeline.

pub mod diagnose;
pub mod forces;
pub mod model;
pub mod parallel;
pub mod progress;
pub mod run;
pub mod step;
pub mod timing;

pub use model::{build_model, GrainBlock, Model};
pub use step::{Reaction, Scratch, Solver, State};
pub use timing::{Stage, StageTimers};
