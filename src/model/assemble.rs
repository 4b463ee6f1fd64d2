//! Mesh-to-model assembly: meshes every grain shape (identical shapes once), places the
//! grains in the scene, and lays them out as one rank's [`Model`]: owned grains first,
//! ghosts after, with physical lumped masses, the contact layout and the
//! prescribed motions. The time step and mass scaling are the solver's
//! (`crate::solver::stable_step`); the initial-overlap check is contact's.

use super::contact_layout::ContactModel;
use super::decomposition::GhostRef;
use super::periodic::{PeriodicCell, NO_IMAGE};
use super::{GrainBlock, Model};
use crate::boundary::{PrescribedMotion, Translation};
use crate::element::{TetReference, TetReferences};
use crate::error::InputError;
use crate::material::{ElasticParameters, MaterialLaw, PlasticParameters};
use crate::mesh::{self, SurfaceMesh, TetMesh};
use crate::scene::{LoadedScene, NodeSelector, ShapeSpec};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Meshes one grain shape in its own frame, in the element and node order the force
/// kernel reads fastest (`mesh::locality`). Identical shapes are meshed once.
pub fn mesh_shape(shape: &ShapeSpec) -> Result<TetMesh, mesh::MeshError> {
    let mesh = match shape {
        ShapeSpec::Sphere(s) => mesh::mesh_sphere(s)?,
        ShapeSpec::Block(b) => mesh::block::mesh_block(b.size, b.divisions),
        ShapeSpec::Surface(s) => mesh::import::mesh_surface(s)?,
    };
    Ok(mesh::locality::order_for_locality(mesh))
}

/// Meshes the scene's distinct surface shapes that are not in the disk cache in worker
/// processes, one per thread of the run (`mesh::import::premesh_in_workers`), so that the
/// serial passes below only load them.
pub fn premesh_surfaces(loaded: &LoadedScene) {
    let distinct: BTreeMap<String, &mesh::import::SurfaceSpec> = loaded
        .scene
        .grains
        .iter()
        .filter_map(|g| match &g.shape {
            ShapeSpec::Surface(s) => Some((serde_json::to_string(s).unwrap_or_default(), s)),
            _ => None,
        })
        .collect();
    let specs: Vec<&mesh::import::SurfaceSpec> = distinct.into_values().collect();
    let workers = rayon::current_num_threads();
    let start = std::time::Instant::now();
    let meshed = mesh::import::premesh_in_workers(&specs, workers);
    if meshed > 0 {
        crate::error::report_line(format_args!(
            "note: meshed {meshed} distinct surface shapes in up to {workers} worker processes ({:.2} s)",
            start.elapsed().as_secs_f64()
        ));
    }
}

/// Builds the model of this rank: the `owned` grains (advanced here) followed by `ghosts`
/// (other ranks' grains and periodic images mirrored for contact; their surfaces are
/// refreshed by the halo exchange or, for images of owned grains, by the solver; their
/// elements only give them the masses their owners use). Both lists are ascending; an
/// image starts at its grain's place shifted by the cell at t = 0.
pub fn build_model_with_ghosts(
    loaded: &LoadedScene,
    owned: &[usize],
    ghosts: &[GhostRef],
) -> Result<(Model, Vec<PrescribedMotion>), InputError> {
    let periodic = PeriodicCell::of_scene(&loaded.scene);
    let at_rest = periodic.as_ref().map(|c| c.at_rest()).unwrap_or_default();
    let scene = &loaded.scene;
    let file = &loaded.path;
    let mat_names: Vec<&String> = scene.materials.keys().collect();
    let materials: Vec<ElasticParameters> = scene
        .materials
        .values()
        .map(|m| ElasticParameters {
            youngs_modulus: m.youngs_modulus,
            poisson_ratio: m.poisson_ratio,
            density: m.density,
        })
        .collect();
    let laws: Vec<MaterialLaw> = materials
        .iter()
        .zip(scene.materials.values())
        .map(|(p, spec)| {
            let plastic = spec.yield_stress.map(|yield_stress| PlasticParameters {
                yield_stress,
                hardening_modulus: spec.hardening_modulus.unwrap_or(0.0),
            });
            MaterialLaw::new(p, spec.law, plastic)
        })
        .collect();

    premesh_surfaces(loaded);
    let mut cache: BTreeMap<String, Arc<TetMesh>> = BTreeMap::new();
    let mut grains = Vec::new();
    let mut x0: Vec<[f64; 3]> = Vec::new();
    let mut tets: Vec<[u32; 4]> = Vec::new();
    let mut tet_law: Vec<u16> = Vec::new();
    let (mut owned_nodes, mut owned_elements) = (0, 0);
    let held = owned
        .iter()
        .map(|&grain| GhostRef {
            grain,
            image: NO_IMAGE,
        })
        .chain(ghosts.iter().copied());
    for (slot, GhostRef { grain: gi, image }) in held.enumerate() {
        let shift = at_rest.offset(image);
        if slot == owned.len() {
            (owned_nodes, owned_elements) = (x0.len(), tets.len());
        }
        let g = &scene.grains[gi];
        let key = serde_json::to_string(&g.shape).unwrap_or_default();
        let m = match cache.get(&key) {
            Some(m) => m.clone(),
            None => {
                let m = Arc::new(mesh_shape(&g.shape).map_err(|e| e.for_grain(file, gi))?);
                mesh::validate(&m).map_err(|e| {
                    InputError::new(file, format!("grains[{gi}].shape"), e.to_string())
                })?;
                cache.insert(key, m.clone());
                m
            }
        };
        let material = mat_names
            .iter()
            .position(|n| **n == g.material)
            .expect("validated");
        let node_base = x0.len();
        let elem_base = tets.len();
        // Node ids are u32 in the model (4 bytes per corner): refuse rather than wrap.
        if u32::try_from(node_base + m.nodes.len()).is_err() {
            return Err(InputError::new(
                file,
                format!("grains[{gi}]"),
                format!(
                    "the rank's model exceeds {} nodes; use more MPI ranks or a coarser seeding",
                    u32::MAX
                ),
            ));
        }
        let quality = mesh::quality(&m);
        let surface_local = mesh::extract_surface(&m);
        for p in &m.nodes {
            x0.push([0, 1, 2].map(|k| p[k] + g.centre[k] + shift[k]));
        }
        for t in &m.tets {
            tets.push(t.map(|n| n + node_base as u32));
            tet_law.push(material as u16);
        }
        let surface = SurfaceMesh {
            nodes: surface_local
                .nodes
                .iter()
                .map(|n| n + node_base as u32)
                .collect(),
            facets: surface_local
                .facets
                .iter()
                .map(|f| f.map(|n| n + node_base as u32))
                .collect(),
        };
        // The bounding sphere is about the shape origin moved to `centre`; for blocks the
        // origin is a corner, so use the node centroid instead.
        let centroid = {
            let mut c = [0.0; 3];
            for p in &x0[node_base..] {
                for i in 0..3 {
                    c[i] += p[i];
                }
            }
            c.map(|v| v / (x0.len() - node_base) as f64)
        };
        let br = x0[node_base..]
            .iter()
            .map(|p| {
                ((p[0] - centroid[0]).powi(2)
                    + (p[1] - centroid[1]).powi(2)
                    + (p[2] - centroid[2]).powi(2))
                .sqrt()
            })
            .fold(0.0, f64::max);
        grains.push(GrainBlock {
            name: g.display_name(gi),
            global_id: gi as u32,
            material,
            nodes: node_base..x0.len(),
            elements: elem_base..tets.len(),
            surface,
            centre0: centroid,
            bounding_radius: br,
            quality,
            image,
        });
    }
    if ghosts.is_empty() {
        (owned_nodes, owned_elements) = (x0.len(), tets.len());
    }

    let plastic_slot = plastic_slots(&laws, &tet_law[..owned_elements]);

    let mut tet_reference = Vec::with_capacity(tets.len());
    for (e, t) in tets.iter().enumerate() {
        let r = TetReference::new(t.map(|n| x0[n as usize])).ok_or_else(|| {
            let gi = grains.partition_point(|g: &GrainBlock| g.elements.end <= e);
            InputError::new(
                file,
                format!("grains[{}]", grains[gi].global_id),
                format!(
                    "element {} is inverted or degenerate",
                    e - grains[gi].elements.start
                ),
            )
        })?;
        tet_reference.push(r);
    }

    // Physical lumped mass: a quarter of each element's mass on each corner. Mass scaling
    // (solver::stable_step) raises `mass` above it where a target step asks for it.
    let n = x0.len();
    let mut physical_mass = vec![0.0; n];
    for (e, t) in tets.iter().enumerate() {
        let m_phys = materials[tet_law[e] as usize].density * tet_reference[e].volume / 4.0;
        for &node in t {
            physical_mass[node as usize] += m_phys;
        }
    }
    // a node no element uses would have neither mass nor stiffness
    let mut used = vec![false; n];
    for t in &tets {
        for &node in t {
            used[node as usize] = true;
        }
    }
    if let Some(orphan) = used.iter().position(|u| !u) {
        let gi = grains.partition_point(|g: &GrainBlock| g.nodes.end <= orphan);
        return Err(InputError::new(
            file,
            format!("grains[{}]", grains[gi].global_id),
            format!(
                "node {} belongs to no element",
                orphan - grains[gi].nodes.start
            ),
        ));
    }

    // Contact layout: surfaces and walls.
    let e_prime: Vec<f64> = materials
        .iter()
        .map(|m| m.youngs_modulus / (1.0 - m.poisson_ratio * m.poisson_ratio))
        .collect();
    let contact = ContactModel::build(scene, &grains, &x0, &e_prime, owned.len());

    // Prescribed motions
    let mut node_grain = vec![0u32; n];
    for (gi, g) in grains.iter().enumerate() {
        for slot in &mut node_grain[g.nodes.clone()] {
            *slot = gi as u32;
        }
    }
    let mut driven = vec![0u8; n];
    let mut motions = Vec::new();
    for (bi, b) in scene.boundaries.iter().enumerate() {
        let Some(grain) = grains[..owned.len()].iter().find(|g| g.name == b.grain) else {
            continue; // grain owned by another rank
        };
        let sel: Vec<u32> = grain
            .nodes
            .clone()
            .filter(|&i| {
                let p = x0[i];
                match &b.select {
                    NodeSelector::All => true,
                    NodeSelector::BeyondPlane { point, normal } => {
                        (p[0] - point[0]) * normal[0]
                            + (p[1] - point[1]) * normal[1]
                            + (p[2] - point[2]) * normal[2]
                            >= 0.0
                    }
                    NodeSelector::FartherThan { point, distance } => dist(&p, point) > *distance,
                    NodeSelector::Within { point, distance } => dist(&p, point) <= *distance,
                }
            })
            .map(|i| i as u32)
            .collect();
        if sel.is_empty() {
            return Err(InputError::new(
                file,
                format!("boundaries[{bi}].select"),
                format!("selects no node of grain '{}'", b.grain),
            ));
        }
        let components = b.components.unwrap_or([true; 3]);
        let mask = components
            .iter()
            .enumerate()
            .fold(0u8, |m, (i, &c)| if c { m | (1 << i) } else { m });
        for &i in &sel {
            if driven[i as usize] & mask != 0 {
                return Err(InputError::new(
                    file,
                    format!("boundaries[{bi}]"),
                    format!(
                        "node {} of grain '{}' is already driven by another boundary",
                        i as usize - grain.nodes.start,
                        b.grain
                    ),
                ));
            }
            driven[i as usize] |= mask;
        }
        let centre0 = b.centre.unwrap_or_else(|| {
            let mut c = [0.0; 3];
            for &i in &sel {
                for k in 0..3 {
                    c[k] += x0[i as usize][k];
                }
            }
            c.map(|v| v / sel.len() as f64)
        });
        let offsets = sel
            .iter()
            .map(|&i| {
                let p = x0[i as usize];
                [p[0] - centre0[0], p[1] - centre0[1], p[2] - centre0[2]]
            })
            .collect();
        let translation = match (&b.velocity, &b.displacement) {
            (Some(v), _) => Translation::Velocity(v.clone()),
            (_, Some(d)) => Translation::Displacement(d.clone()),
            _ => Translation::Fixed,
        };
        motions.push(PrescribedMotion {
            name: b.name.clone(),
            nodes: sel,
            offsets,
            centre0,
            translation,
            angular_velocity: b.angular_velocity.clone(),
            components,
            rotation: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        });
    }

    let local_images = local_images(&grains, owned.len());
    let tet_reference =
        TetReferences::new(&tet_reference, grains.iter().map(|g| g.elements.clone()));
    Ok((
        Model {
            grains,
            materials,
            laws,
            x0,
            tets: tets.into(),
            tet_reference,
            tet_law,
            plastic_slot,
            mass: physical_mass.clone(),
            physical_mass,
            driven,
            dt: 0.0,
            dt_stable: 0.0,
            dt_critical_element: 0,
            added_mass: 0.0,
            scaled_elements: 0,
            gravity: scene.simulation.gravity,
            damping: scene.simulation.damping,
            deformation_damping: scene.simulation.deformation_damping,
            node_grain,
            owned_grains: owned.len(),
            boundary_names: scene.boundaries.iter().map(|b| b.name.clone()).collect(),
            owned_nodes,
            owned_elements,
            contact,
            stages: crate::boundary::stages::StagePlan::build(scene),
            local_images,
            periodic,
        },
        motions,
    ))
}

/// (ghost, owned grain) of every image whose grain is owned here.
fn local_images(grains: &[GrainBlock], owned: usize) -> Vec<(usize, usize)> {
    (owned..grains.len())
        .filter(|&g| grains[g].image != NO_IMAGE)
        .filter_map(|g| {
            let source = grains[..owned]
                .iter()
                .position(|o| o.global_id == grains[g].global_id)?;
            Some((g, source))
        })
        .collect()
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Index of each owned element's plastic state (`NONE` for elastic elements), in element
/// order; empty when no owned element is plastic, so elastic runs carry nothing.
fn plastic_slots(laws: &[MaterialLaw], tet_law: &[u16]) -> Vec<u32> {
    if !tet_law.iter().any(|&l| laws[l as usize].plastic.is_some()) {
        return Vec::new();
    }
    let mut next = 0u32;
    tet_law
        .iter()
        .map(|&l| {
            if laws[l as usize].plastic.is_some() {
                next += 1;
                next - 1
            } else {
                super::NONE
            }
        })
        .collect()
}
