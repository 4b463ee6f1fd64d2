//! Building a solver from a scene: assemble the rank's model (`crate::model`), set the
//! time step and mass scaling ([`super::stable_step`]), check the initial overlap
//! (`crate::contact`), and start from the grains' initial rigid-body velocities.

use super::stable_step::set_time_step_and_mass_scaling;
use super::step::Solver;
use crate::error::Result;
use crate::model::decomposition::GhostRef;
use crate::model::{build_model_with_ghosts, serial_images, Model};
use crate::scene::LoadedScene;

/// Builds the solver of a scene with all grains on this rank.
pub fn build_solver(loaded: &LoadedScene) -> Result<Solver> {
    let owned: Vec<usize> = (0..loaded.scene.grains.len()).collect();
    build_solver_for(loaded, &owned, &serial_images(loaded)?)
}

/// Builds the solver of one rank (input errors name the scene file and field): the `owned` grains (advanced here) and the `ghosts`
/// (other ranks' grains and periodic images mirrored for contact), ascending, at t = 0.
pub fn build_solver_for(
    loaded: &LoadedScene,
    owned: &[usize],
    ghosts: &[GhostRef],
) -> Result<Solver> {
    let (mut model, motions) = build_model_with_ghosts(loaded, owned, ghosts)?;
    set_time_step_and_mass_scaling(&mut model, &loaded.scene.simulation, &loaded.path)?;
    crate::contact::check_initial_overlap(&model, &loaded.path)?;
    let v0 = initial_velocities(&model, loaded);
    Ok(Solver::new(model, motions, v0))
}

/// Initial velocity field: each grain's rigid translation + rotation about its centre.
pub fn initial_velocities(model: &Model, loaded: &LoadedScene) -> Vec<[f64; 3]> {
    let mut v = vec![[0.0; 3]; model.num_nodes()];
    for g in &model.grains {
        let spec = &loaded.scene.grains[g.global_id as usize];
        let (u, w, c) = (spec.velocity, spec.angular_velocity, spec.centre);
        for n in g.nodes.clone() {
            let x = model.x0[n];
            let r = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
            v[n] = [
                u[0] + w[1] * r[2] - w[2] * r[1],
                u[1] + w[2] * r[0] - w[0] * r[2],
                u[2] + w[0] * r[1] - w[1] * r[0],
            ];
        }
    }
    v
}
