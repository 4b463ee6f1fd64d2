//! Frames of `results.h5`: per-node displacement and velocity, per-element Cauchy and
//! von Mises stress and equivalent plastic strain of the owned grains, gathered in global
//! order.

use super::contact_watch::gather_pair_contacts;
use super::grain_motion::grain_motion;
use crate::domain::Domain;
use crate::error::Result;
use crate::io::results::{FieldPart, ResultsWriter};
use crate::material::{cauchy_from_first_piola, von_mises};
use crate::mesh::tet_volume;
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
    let mut contact = vec![[0.0; 3]; m.num_nodes()];
    crate::contact::contact_forces_into(&solver.scratch.contact, &mut contact);
    let contact: Vec<f64> = contact[..nn].iter().flatten().copied().collect();
    let fields = element_fields(solver);
    let gather = |local: &[f64], offsets: &[usize], k: usize| {
        gather_rows(domain, owner, offsets, local, k).unwrap_or_default()
    };
    let disp = gather(&disp, &global.node_offset, 3);
    let vel = gather(&vel, &global.node_offset, 3);
    let contact = gather(&contact, &global.node_offset, 3);
    let stress = gather(&fields.stress[..6 * ne], &global.element_offset, 6);
    let vm = gather(&fields.von_mises[..ne], &global.element_offset, 1);
    let eqps = gather(
        &fields.equivalent_plastic_strain[..ne],
        &global.element_offset,
        1,
    );
    // the rank that advanced each element at this frame (migration moves grains)
    let owner_rank = gather(&vec![domain.rank() as f64; ne], &global.element_offset, 1);
    let grains = grain_records(solver, &fields.stress);
    let grain_offset: Vec<usize> = (0..=owner.len()).collect();
    let grain_disp = gather(&grains.displacement, &grain_offset, 3);
    let grain_rot = gather(&grains.rotation, &grain_offset, 3);
    let grain_stress = gather(&grains.stress, &grain_offset, 6);
    let contacts = contact_records(domain, solver);
    // rank 0 holds the contacts; every rank must state the same dataset sizes
    let mut count = [contacts.sliding.len() as f64];
    domain.sum_in_place(&mut count);
    let (g, c) = (owner.len() as u64, count[0] as u64);
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
            name: "contact_force",
            units: "N",
            components: 3,
            data: &contact,
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
        FieldPart {
            name: "grain_displacement",
            units: "m",
            components: 3,
            data: &grain_disp,
            offset: 0,
            total: g,
        },
        FieldPart {
            name: "grain_rotation",
            units: "rad",
            components: 3,
            data: &grain_rot,
            offset: 0,
            total: g,
        },
        FieldPart {
            name: "grain_stress",
            units: "Pa",
            components: 6,
            data: &grain_stress,
            offset: 0,
            total: g,
        },
        FieldPart {
            name: "contact_grains",
            units: "",
            components: 2,
            data: &contacts.grains,
            offset: 0,
            total: c,
        },
        FieldPart {
            name: "contact_point",
            units: "m",
            components: 3,
            data: &contacts.point,
            offset: 0,
            total: c,
        },
        FieldPart {
            name: "contact_normal",
            units: "1",
            components: 3,
            data: &contacts.normal,
            offset: 0,
            total: c,
        },
        FieldPart {
            name: "contact_normal_force",
            units: "N",
            components: 1,
            data: &contacts.normal_force,
            offset: 0,
            total: c,
        },
        FieldPart {
            name: "contact_tangential_force",
            units: "N",
            components: 1,
            data: &contacts.tangential_force,
            offset: 0,
            total: c,
        },
        FieldPart {
            name: "contact_sliding",
            units: "",
            components: 1,
            data: &contacts.sliding,
            offset: 0,
            total: c,
        },
    ];
    writer.write_frame(index, solver.state.time, &fields)
}

/// Per-grain records of a frame, owned grains in model order: centroid displacement and
/// rotation vector (`super::grain_motion`), and the volume average of the Cauchy stress
/// (xx, yy, zz, yz, xz, xy; Σ σₑ vₑ / Σ vₑ over the grain's elements, vₑ current volumes).
struct GrainRecords {
    displacement: Vec<f64>,
    rotation: Vec<f64>,
    stress: Vec<f64>,
}

fn grain_records(solver: &Solver, element_stress: &[f64]) -> GrainRecords {
    let m = &solver.model;
    let mut r = GrainRecords {
        displacement: Vec::with_capacity(3 * m.owned_grains),
        rotation: Vec::with_capacity(3 * m.owned_grains),
        stress: Vec::with_capacity(6 * m.owned_grains),
    };
    for g in 0..m.owned_grains {
        let motion = grain_motion(m, &solver.state.x, g);
        r.displacement.extend_from_slice(&motion.displacement);
        r.rotation.extend_from_slice(&motion.rotation);
        let (mut sum, mut volume) = ([0.0; 6], 0.0);
        for e in m.grains[g].elements.clone() {
            let v = tet_volume(&m.tets[e].map(|i| solver.state.x[i as usize]));
            volume += v;
            for k in 0..6 {
                sum[k] += v * element_stress[6 * e + k];
            }
        }
        r.stress.extend(sum.map(|s| s / volume));
    }
    r
}

/// Per-contact records of a frame (grain pairs, `crate::contact::fabric`): all on rank 0,
/// empty elsewhere. Grain ids are scene indices (stored as f64, exact).
struct ContactRecords {
    grains: Vec<f64>,
    point: Vec<f64>,
    normal: Vec<f64>,
    normal_force: Vec<f64>,
    tangential_force: Vec<f64>,
    sliding: Vec<f64>,
}

fn contact_records(domain: &Domain, solver: &Solver) -> ContactRecords {
    let pairs =
        gather_pair_contacts(domain, solver, &mut Vec::new(), &mut Vec::new()).unwrap_or_default();
    ContactRecords {
        grains: pairs
            .iter()
            .flat_map(|p| [p.a as f64, p.b as f64])
            .collect(),
        point: pairs.iter().flat_map(|p| p.point).collect(),
        normal: pairs.iter().flat_map(|p| p.normal).collect(),
        normal_force: pairs.iter().map(|p| p.normal_force).collect(),
        tangential_force: pairs.iter().map(|p| p.tangential_force).collect(),
        sliding: pairs
            .iter()
            .map(|p| f64::from(u8::from(p.sliding)))
            .collect(),
    }
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
