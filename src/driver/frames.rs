//! Frames of `results.h5`: per-node displacement, velocity and contact force, per-element
//! Cauchy and von Mises stress and equivalent plastic strain, per-grain records and owning
//! ranks (each rank writes its owned grains' rows), per-contact records (from rank 0).
//! Layout: docs/RESULTS.md.

use super::contact_watch::gather_pair_contacts;
use super::grain_motion::grain_motion;
use crate::domain::Domain;
use crate::error::Result;
use crate::io::results::{grain_row_blocks, FieldPart, ResultsWriter};
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

/// Writes one frame: every rank writes its owned grains' rows (nodes, elements, grain
/// records) straight into the file, in global grain order, with one collective write per
/// field; nothing bulk is gathered. The per-contact records are the exception: they are
/// few (one per touching grain pair) and come out of `gather_pair_contacts` on rank 0
/// already, so rank 0 writes them all. All ranks must call.
pub fn write_frame(
    writer: &mut ResultsWriter,
    domain: &Domain,
    solver: &Solver,
    global: &GlobalMesh,
    index: usize,
) -> Result<()> {
    let m = &solver.model;
    let (nn, ne, ng) = (m.owned_nodes, m.owned_elements, m.owned_grains);
    // This rank's rows in the file: its owned grains, in model order, which is ascending
    // global order (the writer refuses blocks out of order rather than misplace rows).
    let owned = || m.grains[..ng].iter().map(|g| g.global_id as usize);
    let node_blocks = grain_row_blocks(owned(), &global.node_offset);
    let element_blocks = grain_row_blocks(owned(), &global.element_offset);
    let grain_offset: Vec<usize> = (0..=global.meshes.len()).collect();
    let grain_blocks = grain_row_blocks(owned(), &grain_offset);

    // a grain wrapped back into a periodic cell is measured from its shifted reference
    let wrapped = |n: usize| (solver.state).wrapped(m.grains[m.node_grain[n] as usize].global_id);
    let disp: Vec<f64> = (0..nn)
        .flat_map(|n| {
            let (x, x0, w) = (solver.state.x[n], m.x0[n], wrapped(n));
            [0, 1, 2].map(|k| x[k] - x0[k] - w[k])
        })
        .collect();
    let vel = solver.state.v[..nn].as_flattened();
    let mut contact = vec![[0.0; 3]; m.num_nodes()];
    crate::contact::contact_forces_into(&solver.scratch.contact, &mut contact);
    let contact = contact[..nn].as_flattened();
    let fields = element_fields(solver);
    let rank = domain.rank() as f64;
    // the rank that advanced each element and grain at this frame (migration moves grains)
    let owner_rank = vec![rank; ne];
    let owner_rank_of_grain = vec![rank; ng];
    let grains = grain_records(solver, &fields.stress);

    let contacts = contact_records(domain, solver);
    // rank 0 holds the contacts; every rank must state the same dataset sizes
    let c = domain.sum_u64(contacts.sliding.len() as u64);
    let contact_block = [(0, c)];
    let contact_blocks: &[(u64, u64)] = if domain.is_root() && c > 0 {
        &contact_block
    } else {
        &[]
    };

    let (n, e) = (global.total_nodes() as u64, global.total_elements() as u64);
    let g = global.meshes.len() as u64;
    let node = |name, units, components, data| FieldPart {
        name,
        units,
        components,
        data,
        blocks: &node_blocks,
        total: n,
    };
    let element = |name, units, components, data| FieldPart {
        name,
        units,
        components,
        data,
        blocks: &element_blocks,
        total: e,
    };
    let grain = |name, units, components, data| FieldPart {
        name,
        units,
        components,
        data,
        blocks: &grain_blocks,
        total: g,
    };
    let contact_pair = |name, units, components, data| FieldPart {
        name,
        units,
        components,
        data,
        blocks: contact_blocks,
        total: c,
    };
    let fields = [
        node("displacement", "m", 3, &disp),
        node("velocity", "m/s", 3, vel),
        node("contact_force", "N", 3, contact),
        element("stress", "Pa", 6, &fields.stress[..6 * ne]),
        element("von_mises_stress", "Pa", 1, &fields.von_mises[..ne]),
        element("owner_rank", "", 1, &owner_rank),
        element(
            "equivalent_plastic_strain",
            "1",
            1,
            &fields.equivalent_plastic_strain[..ne],
        ),
        grain("grain_displacement", "m", 3, &grains.displacement),
        grain("grain_rotation", "rad", 3, &grains.rotation),
        grain("grain_stress", "Pa", 6, &grains.stress),
        grain("owner_rank_of_grain", "", 1, &owner_rank_of_grain),
        contact_pair("contact_grains", "", 2, &contacts.grains),
        contact_pair("contact_point", "m", 3, &contacts.point),
        contact_pair("contact_normal", "1", 3, &contacts.normal),
        contact_pair("contact_normal_force", "N", 1, &contacts.normal_force),
        contact_pair(
            "contact_tangential_force",
            "N",
            1,
            &contacts.tangential_force,
        ),
        contact_pair("contact_sliding", "", 1, &contacts.sliding),
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
        let w = solver.state.wrapped(m.grains[g].global_id);
        r.displacement
            .extend_from_slice(&[0, 1, 2].map(|k| motion.displacement[k] - w[k]));
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
