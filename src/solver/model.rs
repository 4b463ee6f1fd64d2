//! Set-up: meshes every grain, places it, and lays the model out as structure-of-arrays
//! contiguous per rank (grain = unit of ownership; owned nodes/elements first, ghosts
//! after). Immutable during a run except through [`crate::solver::State`].

use crate::boundary::{PrescribedMotion, Translation};
use crate::contact::ContactModel;
use crate::element::{max_stiffness_eigenvalue, TetReference};
use crate::error::InputError;
use crate::material::{ElasticLaw, ElasticParameters};
use crate::mesh::{self, SurfaceMesh, TetMesh};
use crate::scene::{LoadedScene, NodeSelector, ShapeSpec};
use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::Arc;

/// One grain's slice of the model arrays.
#[derive(Debug, Clone)]
pub struct GrainBlock {
    pub name: String,
    /// Index in the scene's `grains` list (global across ranks).
    pub global_id: u32,
    /// Index into [`Model::materials`].
    pub material: usize,
    pub nodes: Range<usize>,
    pub elements: Range<usize>,
    /// Surface facets and nodes, as model node indices.
    pub surface: SurfaceMesh,
    /// Bounding sphere centre at t = 0 and radius (m).
    pub centre0: [f64; 3],
    pub bounding_radius: f64,
    /// Mesh quality of the grain's mesh.
    pub quality: mesh::QualityReport,
}

/// Compressed node → (element, local corner) incidence, for race-free deterministic
/// gathering of element forces.
#[derive(Debug, Clone, Default)]
pub struct NodeIncidence {
    /// `offsets[n]..offsets[n+1]` indexes `entries` for node n.
    pub offsets: Vec<u32>,
    /// `4·element + corner`.
    pub entries: Vec<u32>,
}

/// The model as laid out on this rank.
#[derive(Debug, Clone)]
pub struct Model {
    pub grains: Vec<GrainBlock>,
    pub materials: Vec<ElasticParameters>,
    pub laws: Vec<ElasticLaw>,
    /// Reference node positions (m).
    pub x0: Vec<[f64; 3]>,
    pub tets: Vec<[u32; 4]>,
    pub tet_reference: Vec<TetReference>,
    /// Material law index per element.
    pub tet_law: Vec<u16>,
    /// Lumped nodal mass after mass scaling (kg).
    pub mass: Vec<f64>,
    /// Physical lumped mass before scaling (kg).
    pub physical_mass: Vec<f64>,
    pub incidence: NodeIncidence,
    /// Bitmask of prescribed translation components per node (bit i = axis i).
    pub driven: Vec<u8>,
    /// Time step used (s).
    pub dt: f64,
    /// Stable time step of the unscaled model (s), including the contact penalty springs
    /// (see `contact.stable_step` for the element-only value), and the element with the
    /// smallest own step.
    pub dt_stable: f64,
    pub dt_critical_element: usize,
    /// Mass added by mass scaling (kg), and the number of scaled elements.
    pub added_mass: f64,
    pub scaled_elements: usize,
    pub gravity: [f64; 3],
    /// Mass-proportional damping α (1/s).
    pub damping: f64,
    /// Mass-proportional damping of each grain's velocity relative to its rigid-body
    /// motion (1/s): damps vibration without any net force or moment on the grain.
    pub deformation_damping: f64,
    /// Grain (index into `grains`) of every node.
    pub node_grain: Vec<u32>,
    /// Surfaces, penalty data and walls for contact.
    pub contact: ContactModel,
    /// Grains, nodes and elements owned (advanced) by this rank: `grains[..owned_grains]`,
    /// nodes `..owned_nodes`, elements `..owned_elements`; the rest are ghosts.
    pub owned_grains: usize,
    pub owned_nodes: usize,
    pub owned_elements: usize,
    /// Names of all prescribed motions of the scene (on every rank, whichever grains it
    /// owns), so that history columns are the same everywhere.
    pub boundary_names: Vec<String>,
}

impl Model {
    pub fn num_nodes(&self) -> usize {
        self.x0.len()
    }
    pub fn num_elements(&self) -> usize {
        self.tets.len()
    }
    /// Total physical mass (kg).
    pub fn total_physical_mass(&self) -> f64 {
        self.physical_mass.iter().sum()
    }
    /// Grain owning a model element.
    pub fn grain_of_element(&self, e: usize) -> usize {
        self.grains.partition_point(|g| g.elements.end <= e)
    }
}

/// Meshes one grain shape in its own frame. Identical shapes are meshed once.
pub fn mesh_shape(shape: &ShapeSpec) -> Result<TetMesh, mesh::MeshError> {
    match shape {
        ShapeSpec::Sphere(s) => mesh::mesh_sphere(s),
        ShapeSpec::Block(b) => Ok(mesh::block::mesh_block(b.size, b.divisions)),
    }
}

/// Builds the model of the given grains (all grains on one rank: `owned = 0..n`).
pub fn build_model(
    loaded: &LoadedScene,
    owned: &[usize],
) -> Result<(Model, Vec<PrescribedMotion>), InputError> {
    build_model_with_ghosts(loaded, owned, &[])
}

/// Builds the model of this rank: the `owned` grains (advanced here) followed by `ghosts`
/// (other ranks' grains mirrored for contact; their surfaces are refreshed by the halo
/// exchange, their elements only give them the masses their owners use). Both lists are
/// global grain ids, ascending.
pub fn build_model_with_ghosts(
    loaded: &LoadedScene,
    owned: &[usize],
    ghosts: &[usize],
) -> Result<(Model, Vec<PrescribedMotion>), InputError> {
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
    let laws: Vec<ElasticLaw> = materials
        .iter()
        .zip(scene.materials.values())
        .map(|(p, spec)| ElasticLaw::new(p, spec.law))
        .collect();

    let mut cache: BTreeMap<String, Arc<TetMesh>> = BTreeMap::new();
    let mut grains = Vec::new();
    let mut x0: Vec<[f64; 3]> = Vec::new();
    let mut tets: Vec<[u32; 4]> = Vec::new();
    let mut tet_law: Vec<u16> = Vec::new();
    let (mut owned_nodes, mut owned_elements) = (0, 0);
    for (slot, &gi) in owned.iter().chain(ghosts).enumerate() {
        if slot == owned.len() {
            (owned_nodes, owned_elements) = (x0.len(), tets.len());
        }
        let g = &scene.grains[gi];
        let key = serde_json::to_string(&g.shape).unwrap_or_default();
        let m = match cache.get(&key) {
            Some(m) => m.clone(),
            None => {
                let m = Arc::new(mesh_shape(&g.shape).map_err(|e| {
                    InputError::new(file, format!("grains[{gi}].shape"), e.to_string())
                })?);
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
        let quality = mesh::quality(&m);
        let surface_local = mesh::extract_surface(&m);
        for p in &m.nodes {
            x0.push([p[0] + g.centre[0], p[1] + g.centre[1], p[2] + g.centre[2]]);
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
        });
    }
    if ghosts.is_empty() {
        (owned_nodes, owned_elements) = (x0.len(), tets.len());
    }

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

    // Stable step per element from the exact element eigenvalue (see element docs).
    let sim = &scene.simulation;
    let elem_dt: Vec<f64> = tet_reference
        .iter()
        .zip(&tet_law)
        .map(|(r, &l)| {
            let law = &laws[l as usize];
            let k = max_stiffness_eigenvalue(r, law.lambda, law.mu);
            let m = materials[l as usize].density * r.volume / 4.0;
            2.0 / (k / m).sqrt()
        })
        .collect();
    let (dt_critical_element, dt_crit) = elem_dt.iter().enumerate().fold(
        (0, f64::INFINITY),
        |acc, (e, &d)| if d < acc.1 { (e, d) } else { acc },
    );
    let dt_stable_elements = sim.dt_safety * dt_crit;

    // Mass scaling: raise an element's density so its own stable step reaches target_dt.
    let n = x0.len();
    let mut physical_mass = vec![0.0; n];
    let mut mass = vec![0.0; n];
    let mut added_mass = 0.0;
    let mut scaled_elements = 0;
    let target = sim.target_dt.map(|t| t / sim.dt_safety);
    let mut elem_scale = vec![1.0; tets.len()];
    for (e, t) in tets.iter().enumerate() {
        let rho = materials[tet_law[e] as usize].density;
        let m_phys = rho * tet_reference[e].volume / 4.0;
        let scale = match target {
            Some(tgt) if elem_dt[e] < tgt => {
                scaled_elements += 1;
                (tgt / elem_dt[e]).powi(2)
            }
            _ => 1.0,
        };
        if e < owned_elements {
            added_mass += 4.0 * m_phys * (scale - 1.0);
        }
        elem_scale[e] = scale;
        for &node in t {
            physical_mass[node as usize] += m_phys;
            mass[node as usize] += m_phys * scale;
        }
    }
    // node → element incidence (CSR)
    let mut counts = vec![0u32; n + 1];
    for t in &tets {
        for &node in t {
            counts[node as usize + 1] += 1;
        }
    }
    for i in 0..n {
        counts[i + 1] += counts[i];
    }
    let mut fill = counts.clone();
    let mut entries = vec![0u32; 4 * tets.len()];
    for (e, t) in tets.iter().enumerate() {
        for (corner, &node) in t.iter().enumerate() {
            let slot = &mut fill[node as usize];
            entries[*slot as usize] = (4 * e + corner) as u32;
            *slot += 1;
        }
    }
    if let Some(orphan) = (0..n).find(|&i| counts[i] == counts[i + 1]) {
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

    // Contact: surfaces, penalty springs in the stable step (and contact-node mass scaling
    // towards target_dt), then the initial-overlap check.
    let e_prime: Vec<f64> = materials
        .iter()
        .map(|m| m.youngs_modulus / (1.0 - m.poisson_ratio * m.poisson_ratio))
        .collect();
    let mut contact = ContactModel::build(scene, &grains, &x0, &e_prime, owned.len());
    let dt_contact = contact.account_stable_step(
        &tets,
        &elem_dt,
        &elem_scale,
        &physical_mass,
        &mut mass,
        sim.dt_safety,
        sim.target_dt,
    );
    added_mass += contact.stable_step.added_mass;
    contact.check_initial_overlap(file, &grains, &x0)?;
    let dt_stable = dt_stable_elements.min(dt_contact);

    // After scaling every element's (and contact node's) own step is ≥ target_dt/safety,
    // so target_dt is stable.
    let scaled_dt = sim.target_dt.unwrap_or(dt_stable);
    let dt = match sim.dt {
        Some(d) => {
            if d > scaled_dt * (1.0 + 1e-12) {
                let why = match contact.stable_step.critical_node {
                    Some(n) if dt_contact < dt_stable_elements && sim.target_dt.is_none() => {
                        format!("contact node {n}")
                    }
                    _ => format!("element {dt_critical_element}"),
                };
                return Err(InputError::new(
                    file,
                    "simulation.dt",
                    format!("{d:e} s exceeds the stable step {scaled_dt:e} s ({why})"),
                ));
            }
            d
        }
        None => scaled_dt,
    };

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

    Ok((
        Model {
            grains,
            materials,
            laws,
            x0,
            tets,
            tet_reference,
            tet_law,
            mass,
            physical_mass,
            incidence: NodeIncidence {
                offsets: counts,
                entries,
            },
            driven,
            dt,
            dt_stable,
            dt_critical_element,
            added_mass,
            scaled_elements,
            gravity: sim.gravity,
            damping: sim.damping,
            deformation_damping: sim.deformation_damping,
            node_grain,
            owned_grains: owned.len(),
            boundary_names: scene.boundaries.iter().map(|b| b.name.clone()).collect(),
            owned_nodes,
            owned_elements,
            contact,
        },
        motions,
    ))
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
