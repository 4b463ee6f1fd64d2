//! Frames of `results.h5`: per-node displacement and velocity, per-element Cauchy and
//! von Mises stress and equivalent plastic strain of the owned grains, gathered in global
//! order.

use crate::domain::Domain;
use crate::error::Result;
use crate::io::results::{FieldPart, ResultsWriter};
use crate::material::{cauchy_from_first_piola, von_mises};
use crate::model::global::GlobalMesh;
use crate::solver::{element_response, Solver};

/// Per-element fields of a frame, in model element order.
pub struct ElementFields {
    /// Cauchy stress (xx, yy, zz, yz, xz, xy; Pa).
    pub stress: Vec<f64>,
    /// von Mises stress of the Cauchy stress (Pa).
    pub von_mises: Vec<f64>,
    /// Equivalent plastic strain α (–; 0 in elastic elements).
    pub equivalent_plastic_strain: Vec<f64>,
}

/// Cauchy stress, von Mises stress and equivalent plastic strain of every element at the
/// current positions, from the committed plastic state (the return mapping is evaluated,
/// not committed, so the fields are those the next step will see).
pub fn element_fields(solver: &Solver) -> ElementFields {
    let m = &solver.model;
    let ne = m.num_elements();
    let mut out = ElementFields {
        stress: Vec::with_capacity(6 * ne),
        von_mises: Vec::with_capacity(ne),
        equivalent_plastic_strain: Vec::with_capacity(ne),
    };
    for e in 0..ne {
        let (f, r) = element_response(m, &solver.state.x, &solver.state.plastic, e);
        let s = cauchy_from_first_piola(&r.first_piola, &f);
        out.stress
            .extend_from_slice(&[s[0], s[4], s[8], s[5], s[2], s[1]]);
        out.von_mises.push(von_mises(&s));
        out.equivalent_plastic_strain
            .push(r.point.map_or(0.0, |p| p.equivalent));
    }
    out
}

/// Writes one frame: every rank contributes its owned grains' rows, rank 0 gathers them in
/// global order and writes them (all ranks must call).
pub fn write_frame(
    writer: &mut ResultsWriter,
    domain: &Domain,
    solver: &Solver,
    global: &GlobalMesh,
    owner: &[u32],
    index: usize,
) -> Result<()> {
    let m = &solver.model;
    let (nn, ne) = (m.owned_nodes, m.owned_elements);
    let disp: Vec<f64> = solver.state.x[..nn]
        .iter()
        .zip(&m.x0[..nn])
        .flat_map(|(x, x0)| [x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]])
        .collect();
    let vel: Vec<f64> = solver.state.v[..nn].iter().flatten().copied().collect();
    let fields = element_fields(solver);
    let gather = |local: &[f64], offsets: &[usize], k: usize| {
        gather_rows(domain, owner, offsets, local, k).unwrap_or_default()
    };
    let disp = gather(&disp, &global.node_offset, 3);
    let vel = gather(&vel, &global.node_offset, 3);
    let stress = gather(&fields.stress[..6 * ne], &global.element_offset, 6);
    let vm = gather(&fields.von_mises[..ne], &global.element_offset, 1);
    let eqps = gather(
        &fields.equivalent_plastic_strain[..ne],
        &global.element_offset,
        1,
    );
    // the rank that advanced each element at this frame (migration moves grains)
    let owner_rank = gather(&vec![domain.rank() as f64; ne], &global.element_offset, 1);
    let (n, e) = (global.total_nodes() as u64, global.total_elements() as u64);
    let fields = [
        FieldPart {
            name: "displacement",
            units: "m",
            components: 3,
            data: &disp,
            offset: 0,
            total: n,
        },
        FieldPart {
            name: "velocity",
            units: "m/s",
            components: 3,
            data: &vel,
            offset: 0,
            total: n,
        },
        FieldPart {
            name: "stress",
            units: "Pa",
            components: 6,
            data: &stress,
            offset: 0,
            total: e,
        },
        FieldPart {
            name: "von_mises_stress",
            units: "Pa",
            components: 1,
            data: &vm,
            offset: 0,
            total: e,
        },
        FieldPart {
            name: "owner_rank",
            units: "",
            components: 1,
            data: &owner_rank,
            offset: 0,
            total: e,
        },
        FieldPart {
            name: "equivalent_plastic_strain",
            units: "1",
            components: 1,
            data: &eqps,
            offset: 0,
            total: e,
        },
    ];
    writer.write_frame(index, solver.state.time, &fields)
}

/// Gathers a per-node (or per-element) field of the owned grains to rank 0 in global
/// order. `per_grain[g]` is the row count of grain g; `local` holds this rank's owned
/// grains' rows (ascending global id), `k` values per row. All ranks must call; rank 0
/// gets `Some(global rows)`.
pub fn gather_rows(
    domain: &Domain,
    owner: &[u32],
    offsets: &[usize],
    local: &[f64],
    k: usize,
) -> Option<Vec<f64>> {
    let all = domain.gather_f64_to_root(local)?;
    let total = *offsets.last().unwrap_or(&0);
    let mut out = vec![0.0; total * k];
    let mut cursor = 0;
    for r in 0..domain.size() {
        for (g, &o) in owner.iter().enumerate() {
            if o as usize == r {
                let rows = offsets[g + 1] - offsets[g];
                out[offsets[g] * k..(offsets[g] + rows) * k]
                    .copy_from_slice(&all[cursor..cursor + rows * k]);
                cursor += rows * k;
            }
        }
    }
    Some(out)
}
