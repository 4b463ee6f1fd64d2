//! Ghost and migration machinery without MPI: the halo plan maps an owner's surface nodes
//! onto the receiver's ghost nodes in the same order, and a grain packed from one solver
//! and unpacked into another arrives with its exact state.

use mufe::domain::halo::HaloPlan;
use mufe::driver::migration::{pack_grain, unpack_grains};
use mufe::model::decomposition::Decomposition;
use mufe::model::global::ghost_margin;
use mufe::model::GlobalMesh;
use mufe::scene::load_scene;
use mufe::solver::{build_solver, build_solver_for, Solver};
use std::path::Path;

fn assembly() -> mufe::scene::LoadedScene {
    load_scene(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/tests/assembly.toml"),
        &[],
    )
    .unwrap()
}

fn rank_solver(loaded: &mufe::scene::LoadedScene, plan: &Decomposition) -> Solver {
    build_solver_for(loaded, &plan.owned, &plan.ghosts).unwrap()
}

#[test]
fn halo_plans_of_two_ranks_pair_up_node_for_node() {
    let loaded = assembly();
    let global = GlobalMesh::build(&loaded).unwrap();
    let owner: Vec<u32> = (0..27).map(|g| if g < 14 { 0 } else { 1 }).collect();
    let margin = ghost_margin(&global);
    let plans: Vec<Decomposition> = (0..2)
        .map(|r| Decomposition::plan(&owner, &global.bounds, margin, r, None))
        .collect();
    assert!(
        !plans[0].ghosts.is_empty() && !plans[1].ghosts.is_empty(),
        "contacts straddle the cut"
    );
    let solvers: Vec<Solver> = plans.iter().map(|p| rank_solver(&loaded, p)).collect();
    let halos: Vec<HaloPlan> = (0..2)
        .map(|r| HaloPlan::new(&solvers[r].model, &plans[r]))
        .collect();
    for r in 0..2 {
        let q = 1 - r;
        let (_, send) = &halos[r].sends[0];
        let (_, recv) = &halos[q].receives[0];
        assert_eq!(send.len(), recv.len());
        // the k-th value sent is the k-th ghost node received: same grain, same node
        for (&s, &g) in send.iter().zip(recv) {
            let (ms, mg) = (&solvers[r].model, &solvers[q].model);
            let gs = &ms.grains[ms.node_grain[s as usize] as usize];
            let gg = &mg.grains[mg.node_grain[g as usize] as usize];
            assert_eq!(gs.global_id, gg.global_id);
            assert_eq!(s as usize - gs.nodes.start, g as usize - gg.nodes.start);
            assert!(g as usize >= mg.owned_nodes, "received into ghost nodes");
            assert_eq!(ms.x0[s as usize], mg.x0[g as usize]);
        }
    }
}

#[test]
fn periodic_images_pair_up_node_for_node_shifted_by_the_cell() {
    let loaded = load_scene(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/periodic/thornton_cell.toml"),
        &[],
    )
    .unwrap();
    let global = GlobalMesh::build(&loaded).unwrap();
    let cell = mufe::model::periodic::PeriodicCell::of_scene(&loaded.scene).unwrap();
    let at = Some(mufe::model::decomposition::PlanCell {
        cell: &cell,
        length: cell.length0,
    });
    let owner = [0, 0, 1, 1];
    let margin = ghost_margin(&global);
    let plans: Vec<Decomposition> = (0..2)
        .map(|r| Decomposition::plan(&owner, &global.bounds, margin, r, at))
        .collect();
    let solvers: Vec<Solver> = plans.iter().map(|p| rank_solver(&loaded, p)).collect();
    let halos: Vec<HaloPlan> = (0..2)
        .map(|r| HaloPlan::new(&solvers[r].model, &plans[r]))
        .collect();
    let at_rest = cell.at_rest();
    for r in 0..2 {
        let q = 1 - r;
        // every one of the 12 neighbours of each owned sphere is held: as the other rank's
        // grain, its image, or an image of an own grain (copied locally)
        let m = &solvers[r].model;
        assert_eq!(
            m.grains.len() - m.owned_grains,
            plans[r].ghosts.len(),
            "one model grain per ghost"
        );
        assert!(!m.local_images.is_empty(), "images of own grains");
        let ((_, send), images) = (&halos[r].sends[0], &halos[r].send_images[0]);
        let (_, recv) = &halos[q].receives[0];
        assert_eq!(send.len(), recv.len());
        for ((&s, &g), &image) in send.iter().zip(recv).zip(images) {
            let (ms, mg) = (&solvers[r].model, &solvers[q].model);
            let gs = &ms.grains[ms.node_grain[s as usize] as usize];
            let gg = &mg.grains[mg.node_grain[g as usize] as usize];
            assert_eq!((gs.global_id, image), (gg.global_id, gg.image));
            let shift = at_rest.offset(image);
            let expected: Vec<f64> = (0..3).map(|k| ms.x0[s as usize][k] + shift[k]).collect();
            assert_eq!(expected, mg.x0[g as usize].to_vec());
        }
    }
}

#[test]
fn a_packed_grain_arrives_with_its_exact_state() {
    let loaded = assembly();
    let mut serial = build_solver(&loaded).unwrap();
    for _ in 0..300 {
        serial.step().unwrap();
    }
    assert!(
        !serial.state.contact.history.is_empty(),
        "friction history exists to migrate"
    );
    // pack the centre grain (13) and one with friction history, unpack into a fresh solver
    let with_history = serial.state.contact.history[0].key.grain as usize;
    let mut data = Vec::new();
    for g in [13usize, with_history] {
        pack_grain(&serial, g, &mut data);
    }
    let mut fresh = build_solver(&loaded).unwrap();
    let installed = unpack_grains(&mut fresh, &data).unwrap();
    assert_eq!(installed.len(), 2);
    for g in [13usize, with_history] {
        let nodes = serial.model.grains[g].nodes.clone();
        assert_eq!(
            &serial.state.x[nodes.clone()],
            &fresh.state.x[nodes.clone()]
        );
        assert_eq!(&serial.state.v[nodes.clone()], &fresh.state.v[nodes]);
        let a: Vec<_> = serial
            .state
            .contact
            .history
            .iter()
            .filter(|p| p.key.grain as usize == g)
            .collect();
        let b: Vec<_> = fresh
            .state
            .contact
            .history
            .iter()
            .filter(|p| p.key.grain as usize == g)
            .collect();
        assert_eq!(a, b, "friction history of grain {g}");
    }
    // a malformed package is an error, not a panic
    assert!(unpack_grains(&mut fresh, &data[..data.len() - 3]).is_err());
}
