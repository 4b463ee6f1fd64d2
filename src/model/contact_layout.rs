//! The static contact layout of a model: every grain's surface as flat arrays (nodes with
//! tributary areas and mean edge lengths, facets with their neighbours, vertex → facet
//! incidence), the penalty and damping settings, and the rigid walls with their prescribed
//! kinematics. Built once with the model; `crate::contact` evaluates contact on it and
//! `crate::solver::stable_step` accounts for its penalty springs in the time step.

use super::GrainBlock;
use crate::boundary::Translation;
use crate::math::{add, cross, norm, scale, sub};
use crate::scene::Scene;
use std::ops::Range;

/// Default penalty factor: the nodal contact spring is this many times stiffer than the
/// local surface stiffness of the mesh (see module docs), so the penetration is ~1/20 of the
/// local elastic approach at the scale of one element, ≈ 1 % of the Hertz approach when the
/// contact radius spans 2–3 elements and less beyond (measured in the hard-case tests and
/// reported by `mufe run` as max penetration).
pub const DEFAULT_PENALTY_FACTOR: f64 = 20.0;
/// Default normal contact damping (fraction of the critical damping of each contact point's
/// penalty spring on its slave node's mass). See the module docs.
pub const DEFAULT_CONTACT_DAMPING: f64 = 0.05;
/// Default broad-phase margin as a fraction of the smallest surface edge of the scene.
pub const DEFAULT_MARGIN_FRACTION: f64 = 0.5;
/// "No such index" marker in index arrays.
pub const NONE: u32 = u32::MAX;
/// One grain's part of the flat surface arrays.
#[derive(Debug, Clone, Default)]
pub struct GrainSurface {
    /// Range into the flat surface-node arrays.
    pub nodes: Range<usize>,
    /// Range into the flat facet arrays.
    pub facets: Range<usize>,
    /// Global id of the grain.
    pub global_id: u32,
    /// The grain is advanced by this rank (false: a ghost mirrored from another rank).
    /// Energies, statistics and wall contacts count owned slave nodes only, so that the
    /// sums over ranks equal the serial ones.
    pub owned: bool,
    /// Periodic image shift of the grain (all zero but for images).
    pub image: super::periodic::Image,
    /// First model node of the grain (for node indices within the grain).
    pub node_base: u32,
    /// Plane-strain modulus E/(1−ν²) of the grain's material (Pa).
    pub e_prime: f64,
    /// Smallest / largest mean surface edge length at a node (m).
    pub h_min: f64,
    pub h_max: f64,
    /// Smallest surface edge of the grain (m).
    pub min_edge: f64,
}

impl GrainSurface {
    /// This rank moves the surface's nodes: an owned grain, or a periodic image (shifted
    /// here from its grain). A plain ghost's nodes are its owner's, and with a trimmed halo
    /// most of them are dormant copies.
    pub fn moves_here(&self) -> bool {
        self.owned || self.image != super::periodic::NO_IMAGE
    }
}

/// How contact changes the stable step (set up once).
#[derive(Debug, Clone, Default)]
pub struct StableStepReport {
    /// Stable step from the elements alone (s, with the safety factor, physical masses).
    pub element_dt: f64,
    /// Stable step of the contact nodes (s, with the safety factor, physical masses);
    /// infinite when no grain can touch another.
    pub contact_dt: f64,
    /// Model node that sets `contact_dt`.
    pub critical_node: Option<usize>,
    /// Contact nodes whose mass was raised to reach `target_dt`, and the mass added (kg).
    pub scaled_nodes: usize,
    pub added_mass: f64,
    /// Largest ε_n of a node (Pa/m).
    pub max_penalty: f64,
}

/// Static contact data of the model (built once, immutable during a run).
#[derive(Debug, Clone, Default)]
pub struct ContactModel {
    /// Coulomb μ between grains.
    pub friction: f64,
    pub penalty_factor: f64,
    /// Normal contact damping ζ (fraction of critical).
    pub damping: f64,
    /// Broad-phase margin (m).
    pub margin: f64,
    /// The scene has at least two grains.
    pub grain_contact: bool,
    /// Per model grain.
    pub surfaces: Vec<GrainSurface>,
    /// Flat surface nodes: model node id, tributary area (m², reference), mean edge (m).
    pub node: Vec<u32>,
    pub node_area: Vec<f64>,
    pub node_h: Vec<f64>,
    /// Flat facets (model node ids, outward orientation) and the facet across each edge
    /// (edge k joins corners k and k+1).
    pub facet: Vec<[u32; 3]>,
    pub facet_adjacent: Vec<[u32; 3]>,
    /// Facets around each flat surface node (CSR).
    pub vertex_facet_offsets: Vec<u32>,
    pub vertex_facets: Vec<u32>,
    /// Aligned with `vertex_facets`: the facet's other two corners (model node ids) in its
    /// orientation order after the vertex. The vertex normals read their edges from here,
    /// one dependent load shorter than through the facet (the contact stage waits on
    /// exactly such chains of misses).
    pub vertex_fans: Vec<[u32; 2]>,
    /// Model node → flat surface index, or [`NONE`].
    pub surface_index: Vec<u32>,
    pub walls: Vec<Wall>,
    /// Smallest surface edge of the scene (m).
    pub min_edge: f64,
    /// Largest plane-strain modulus E/(1−ν²) of any material of the scene (Pa): the same
    /// on every rank, whichever grains it holds.
    pub e_prime_max: f64,
    pub stable_step: StableStepReport,
}

impl ContactModel {
    /// Builds the surface data of the grains (model node ids) and binds the walls.
    pub fn build(
        scene: &Scene,
        grains: &[GrainBlock],
        x0: &[[f64; 3]],
        e_prime: &[f64],
        owned_grains: usize,
    ) -> ContactModel {
        let spec = &scene.contact;
        let mut cm = ContactModel {
            friction: spec.friction,
            penalty_factor: spec.penalty_factor.unwrap_or(DEFAULT_PENALTY_FACTOR),
            damping: spec.damping.unwrap_or(DEFAULT_CONTACT_DAMPING),
            grain_contact: scene.grains.len() >= 2,
            surface_index: vec![NONE; x0.len()],
            min_edge: f64::INFINITY,
            ..Default::default()
        };
        let mut edges: Vec<(u32, u32, u32)> = Vec::new();
        cm.e_prime_max = e_prime.iter().cloned().fold(0.0, f64::max);
        for (gi, g) in grains.iter().enumerate() {
            let n0 = cm.node.len();
            let f0 = cm.facet.len();
            for (k, &n) in g.surface.nodes.iter().enumerate() {
                cm.surface_index[n as usize] = (n0 + k) as u32;
                cm.node.push(n);
            }
            cm.node_area.resize(cm.node.len(), 0.0);
            let (node_h, min_edge) = crate::mesh::mean_edge_at_nodes(&g.surface, x0);
            cm.node_h.extend(node_h);
            for f in &g.surface.facets {
                let p = f.map(|n| x0[n as usize]);
                let area = 0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
                for k in 0..3 {
                    let s = cm.surface_index[f[k] as usize] as usize;
                    cm.node_area[s] += area / 3.0;
                }
                cm.facet.push(*f);
            }
            // facet adjacency by matching each directed edge (a, b) with (b, a)
            edges.clear();
            for (fi, f) in cm.facet[f0..].iter().enumerate() {
                for k in 0..3 {
                    let (a, b) = (f[k], f[(k + 1) % 3]);
                    edges.push((a.min(b), a.max(b), ((f0 + fi) * 3 + k) as u32));
                }
            }
            edges.sort_unstable();
            cm.facet_adjacent.resize(cm.facet.len(), [NONE; 3]);
            for w in edges.windows(2) {
                if w[0].0 == w[1].0 && w[0].1 == w[1].1 {
                    let (fa, ka) = ((w[0].2 / 3) as usize, (w[0].2 % 3) as usize);
                    let (fb, kb) = ((w[1].2 / 3) as usize, (w[1].2 % 3) as usize);
                    cm.facet_adjacent[fa][ka] = fb as u32;
                    cm.facet_adjacent[fb][kb] = fa as u32;
                }
            }
            let hs = &cm.node_h[n0..];
            cm.surfaces.push(GrainSurface {
                nodes: n0..cm.node.len(),
                facets: f0..cm.facet.len(),
                global_id: g.global_id,
                owned: gi < owned_grains,
                image: g.image,
                node_base: g.nodes.start as u32,
                e_prime: e_prime[g.material],
                h_min: hs.iter().cloned().fold(f64::INFINITY, f64::min),
                h_max: hs.iter().cloned().fold(0.0, f64::max),
                min_edge,
            });
            cm.min_edge = cm.min_edge.min(min_edge);
        }
        // vertex → facets
        let n = cm.node.len();
        let mut offsets = vec![0u32; n + 1];
        for f in &cm.facet {
            for &v in f {
                offsets[cm.surface_index[v as usize] as usize + 1] += 1;
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut entries = vec![0u32; offsets[n] as usize];
        let mut fans = vec![[0u32; 2]; offsets[n] as usize];
        for (fi, f) in cm.facet.iter().enumerate() {
            for &v in f {
                // the first corner that is v, as for a facet that repeats a node
                let j = f.iter().position(|&c| c == v).unwrap_or(0);
                let s = cm.surface_index[v as usize] as usize;
                entries[fill[s] as usize] = fi as u32;
                fans[fill[s] as usize] = [f[(j + 1) % 3], f[(j + 2) % 3]];
                fill[s] += 1;
            }
        }
        cm.vertex_facet_offsets = offsets;
        cm.vertex_facets = entries;
        cm.vertex_fans = fans;
        if !cm.min_edge.is_finite() {
            cm.min_edge = 0.0;
        }
        cm.margin = spec.margin.unwrap_or(DEFAULT_MARGIN_FRACTION * cm.min_edge);
        cm.walls = scene
            .walls
            .iter()
            .map(|w| {
                let l = norm(w.normal);
                Wall {
                    name: w.name.clone(),
                    point0: w.point,
                    normal: scale(w.normal, 1.0 / l),
                    friction: w.friction,
                    translation: match (&w.velocity, &w.displacement) {
                        (Some(v), _) => Translation::Velocity(v.clone()),
                        (_, Some(d)) => Translation::Displacement(d.clone()),
                        _ => Translation::Fixed,
                    },
                }
            })
            .collect();
        cm
    }

    /// Whether contact does anything in this model (two grains or a wall).
    pub fn active(&self) -> bool {
        self.grain_contact || !self.walls.is_empty()
    }

    /// Penalty ε_n (Pa/m) for a slave node of mean edge `h_s` against a master point of
    /// mean edge `h_m`, with `e_prime` the plane-strain modulus of the stiffer side.
    #[inline]
    pub fn penalty(&self, e_prime: f64, h_s: f64, h_m: f64) -> f64 {
        self.penalty_factor * e_prime * h_s.min(h_m) / (h_s * h_s)
    }
}

/// A rigid plane wall bound to the model (set up from a `WallSpec`).
#[derive(Debug, Clone)]
pub struct Wall {
    pub name: String,
    /// Point of the plane at t = 0 (m).
    pub point0: [f64; 3],
    /// Unit normal pointing into the grains' side.
    pub normal: [f64; 3],
    /// Coulomb μ against grains.
    pub friction: f64,
    /// Prescribed motion (`Fixed` for a wall driven by its state: see
    /// `crate::boundary::stages`).
    pub translation: Translation,
}

impl Wall {
    /// Displacement of the wall from t = 0 (m).
    #[inline]
    pub fn displacement_at(&self, t: f64) -> [f64; 3] {
        self.translation.displacement_at(t)
    }

    /// Point of the plane after displacement `u`.
    #[inline]
    pub fn point_at_displacement(&self, u: [f64; 3]) -> [f64; 3] {
        add(self.point0, u)
    }
}
