//! The solver's `State` holds everything that evolves: serialised in the middle of a run
//! and restored into a fresh solver built from the same scene, the run continues with a
//! bitwise-identical history and ends in an identical state. This is what checkpoints
//! and restart stand on; a field that evolves outside `State` breaks it.

use mufe::driver::history_row;
use mufe::scene::load_scene;
use mufe::solver::{build_solver, Solver, State};
use std::path::Path;

fn solver_for(scene: &str) -> (mufe::scene::LoadedScene, Solver) {
    solver_with(scene, &[])
}

fn solver_with(scene: &str, sets: &[String]) -> (mufe::scene::LoadedScene, Solver) {
    let loaded = load_scene(&Path::new(env!("CARGO_MANIFEST_DIR")).join(scene), sets).unwrap();
    let solver = build_solver(&loaded).expect("model builds");
    (loaded, solver)
}

/// Advances `steps` steps and returns one history row per step.
fn advance(solver: &mut Solver, steps: usize) -> Vec<Vec<f64>> {
    let mut rows = Vec::new();
    for _ in 0..steps {
        solver.step().expect("step");
        let mut row = Vec::new();
        history_row(solver, &mut row);
        rows.push(row);
    }
    rows
}

fn assert_bitwise(a: &[Vec<f64>], b: &[Vec<f64>], what: &str) {
    assert_eq!(a.len(), b.len());
    for (i, (ra, rb)) in a.iter().zip(b).enumerate() {
        for (k, (x, y)) in ra.iter().zip(rb).enumerate() {
            assert_eq!(
                x.to_bits(),
                y.to_bits(),
                "{what}: row {i}, column {k}: restored {y:e}, uninterrupted {x:e}"
            );
        }
    }
}

/// Runs `before` steps, serialises the state to JSON, runs `after` more; a second solver
/// built from the scene restores the JSON and runs `after` steps.
fn round_trip(scene: &str, before: usize, after: usize) -> State {
    round_trip_with(scene, &[], before, after)
}

fn round_trip_with(scene: &str, sets: &[String], before: usize, after: usize) -> State {
    let (_, mut original) = solver_with(scene, sets);
    advance(&mut original, before);
    let json = serde_json::to_string(&original.state).expect("state serialises");
    let expected = advance(&mut original, after);

    let (_, mut restored) = solver_with(scene, sets);
    let state: State = serde_json::from_str(&json).expect("state deserialises");
    let mid = state.clone();
    restored.restore(state).expect("state fits the model");
    let got = advance(&mut restored, after);
    assert_bitwise(&expected, &got, scene);
    assert!(
        original.state == restored.state,
        "{scene}: final states differ"
    );
    mid
}

#[test]
fn assembly_with_friction_walls_and_contact_lists_restores_bitwise() {
    let mid = round_trip("jobs/tests/assembly.toml", 260, 140);
    // the restore point really carries what must be restored
    let c = &mid.contact;
    assert!(
        !c.history.is_empty(),
        "friction history at the restore point"
    );
    assert!(
        c.detection.built && c.detection.rebuilds > 0,
        "candidate lists built before the restore point"
    );
    assert!(
        mid.contact.walls.iter().any(|w| w.contacts > 0),
        "a wall touches"
    );
    assert!(mid.supplied_energy > 0.0);
}

#[test]
fn elastic_plastic_assembly_restores_bitwise_with_its_plastic_state() {
    // impacts at 3 m/s against σy = 100 MPa: grains yield at their contacts before step 270
    let sets = [
        "materials.glass.yield_stress=1e8".to_string(),
        "materials.glass.hardening_modulus=1e9".to_string(),
    ];
    let mid = round_trip_with("jobs/tests/assembly.toml", &sets, 270, 80);
    assert!(
        mid.plastic.iter().any(|p| p.equivalent > 0.0),
        "plastic flow before the restore point"
    );
    assert!(mid.energy.plastic_dissipation > 0.0);
}

#[test]
fn prescribed_motions_restore_bitwise() {
    let mid = round_trip("jobs/demo/sphere_compression.toml", 120, 80);
    assert!(mid
        .reactions
        .iter()
        .any(|r| r.force.iter().any(|f| *f != 0.0)));
}

#[test]
fn a_state_of_another_scene_is_refused() {
    let (_, sphere) = solver_for("jobs/demo/sphere_compression.toml");
    let (_, mut assembly) = solver_for("jobs/tests/assembly.toml");
    let err = assembly.restore(sphere.state.clone()).unwrap_err();
    assert!(err.to_string().contains("does not fit"), "{err}");
}

#[test]
fn servo_state_round_trip_mid_run_continues_identically() {
    let mid = round_trip("jobs/tests/servo_sphere.toml", 3000, 1500);
    let servo = mid.contact.walls[1].servo.expect("servo state in State");
    assert!(servo.filtered_force > 0.0 && servo.displacement != 0.0);
}

#[test]
fn a_branch_with_another_time_step_continues_the_clock_from_the_checkpoint() {
    // a branch with more mass scaling (a longer Δt) must not restart time at n·Δt_new
    let (_, mut original) = solver_for("jobs/demo/sphere_compression.toml");
    advance(&mut original, 120);
    let (t0, n0, dt0) = (original.state.time, original.state.step, original.model.dt);
    let longer = format!("simulation.target_dt={:e}", 2.0 * dt0);
    let (_, mut branch) = solver_with("jobs/demo/sphere_compression.toml", &[longer]);
    let dt1 = branch.model.dt;
    assert!(
        dt1 > 1.5 * dt0,
        "the branch's Δt {dt1:e} is longer than {dt0:e}"
    );
    branch.restore(original.state.clone()).unwrap();
    assert_eq!((branch.state.time, branch.state.step), (t0, n0));
    advance(&mut branch, 10);
    let expected = t0 + 10.0 * dt1;
    assert!(
        (branch.state.time - expected).abs() < 1e-9 * expected,
        "t = {:e} after 10 steps of {dt1:e} from {t0:e}",
        branch.state.time
    );
    // an ordinary restart keeps the clock as it was: t_n = n·Δt exactly
    let (_, mut same) = solver_for("jobs/demo/sphere_compression.toml");
    same.restore(original.state.clone()).unwrap();
    advance(&mut same, 10);
    assert_eq!(same.state.time, (n0 + 10) as f64 * dt0);
}
