//! The t = 0 overlap check: a scene whose grains start inside each other (or behind a
//! wall) by more than a small fraction of the local surface edge is an input error, since
//! the penalty springs would release that overlap as a spurious explosion.

use super::broad::{BroadPhase, CandidateLists, DetectionReference};
use super::narrow::{evaluate_entry, EvalContext};
use super::OVERLAP_TOLERANCE;
use crate::error::InputError;
use crate::math::{dot, sub};
use crate::model::Model;

/// Fails with an input error naming both grains (or the wall and the grain) when any
/// surface node starts inside another grain, or behind a wall, by more than
/// [`OVERLAP_TOLERANCE`] × the smallest surface edge involved.
pub fn check_initial_overlap(model: &Model, file: &str) -> Result<(), InputError> {
    let (cm, grains, x0) = (&model.contact, &model.grains, &model.x0);
    if !cm.active() {
        return Ok(());
    }
    let mut broad = BroadPhase::default();
    let mut lists = CandidateLists::default();
    let wall0 = vec![[0.0; 3]; cm.walls.len()];
    broad.rebuild(
        cm,
        x0,
        &wall0,
        &mut lists,
        &mut DetectionReference::default(),
        cm.margin,
        0,
    );
    let zeros = vec![[0.0; 3]; x0.len()];
    let ctx = EvalContext {
        cm,
        passes: &lists.passes,
        facets: &lists.candidate_facets,
        x: x0,
        v: &zeros,
        mass: &[],
        dt: 0.0,
        history: &[],
        friction: false,
    };
    let mut worst: Option<(f64, usize, usize)> = None;
    let mut touching = Vec::new();
    lists.within_reach(0.0, &[], &mut touching);
    for i in touching {
        let e = &lists.entries[i as usize];
        let r = evaluate_entry(&ctx, e);
        if !r.active {
            continue;
        }
        let p = lists.passes[e.pass as usize];
        let (a, b) = (p.slave as usize, p.master as usize);
        let tol = OVERLAP_TOLERANCE * cm.surfaces[a].min_edge.min(cm.surfaces[b].min_edge);
        // a NaN gap (coincident nodes) counts as overlap
        if (r.gap > tol || r.gap.is_nan()) && worst.is_none_or(|w| r.gap > w.0 || r.gap.is_nan()) {
            worst = Some((r.gap, a.min(b), a.max(b)));
        }
    }
    if let Some((g, a, b)) = worst {
        let tol = OVERLAP_TOLERANCE * cm.surfaces[a].min_edge.min(cm.surfaces[b].min_edge);
        return Err(InputError::new(
            file,
            format!("grains[{}] and grains[{}]", grains[a].global_id, grains[b].global_id),
            format!(
                "'{}' and '{}' overlap by {g:.3e} m at t = 0 (tolerance {tol:.3e} m = {OVERLAP_TOLERANCE} × smallest surface edge); move them apart",
                grains[a].name, grains[b].name
            ),
        ));
    }
    for &(w, k) in &lists.wall_nodes {
        let wall = &cm.walls[w as usize];
        let k = k as usize;
        let depth = -dot(sub(x0[cm.node[k] as usize], wall.point0), wall.normal);
        let g = cm.surfaces.partition_point(|s| s.nodes.end <= k);
        let tol = OVERLAP_TOLERANCE * cm.surfaces[g].min_edge;
        if depth > tol || depth.is_nan() {
            return Err(InputError::new(
                file,
                format!("walls[{w}] and grains[{}]", grains[g].global_id),
                format!(
                    "grain '{}' starts {depth:.3e} m behind wall '{}' (tolerance {tol:.3e} m); move the grain or the wall",
                    grains[g].name, wall.name
                ),
            ));
        }
    }
    Ok(())
}
