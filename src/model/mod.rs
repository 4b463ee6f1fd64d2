//! The static model layer: how the grains of a scene are laid out on one rank.
//!
//! [`Model`] holds the mesh of every grain this rank owns or mirrors, placed in the scene
//! and flattened into structure-of-arrays (owned grains first, ghosts after), with
//! lumped masses, prescribed-node masks and the static contact layout
//! ([`contact_layout`]). It is built once ([`assemble`]) and read by contact, solver,
//! domain, io and the driver; it depends on none of them (only on scene, mesh, material,
//! element and boundary below it). What changes during a run lives in
//! `crate::solver::State`.
//!
//! [`decomposition`] says which grains a rank owns and mirrors; [`global`] is the whole
//! scene's mesh layout, identical on every rank.

pub mod assemble;
pub mod contact_layout;
pub mod decomposition;
pub mod global;
pub mod periodic;

pub use assemble::{build_model_with_ghosts, mesh_shape};
pub use contact_layout::{ContactModel, NONE};
pub use global::{serial_images, GlobalMesh};

use crate::element::TetReferences;
use crate::lanes::Connectivity;
use crate::material::{ElasticParameters, MaterialLaw};
use crate::mesh::{self, SurfaceMesh};
use std::ops::Range;

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
    /// Periodic image shift of a ghost (all zero for grains and plain ghosts).
    pub image: periodic::Image,
}

/// The model as laid out on this rank.
#[derive(Debug, Clone)]
pub struct Model {
    pub grains: Vec<GrainBlock>,
    pub materials: Vec<ElasticParameters>,
    pub laws: Vec<MaterialLaw>,
    /// Reference node positions (m).
    pub x0: Vec<[f64; 3]>,
    pub tets: Connectivity,
    /// Dm⁻¹ and V0 of every element, lane-blocked for the force kernel.
    pub tet_reference: TetReferences,
    /// Material law index per element.
    pub tet_law: Vec<u16>,
    /// Index into `State::plastic` of each owned element of a plastic material, [`NONE`]
    /// for elastic ones; empty when this rank owns no plastic element. Slots follow element
    /// order, so a grain's plastic states are contiguous.
    pub plastic_slot: Vec<u32>,
    /// Lumped nodal mass after mass scaling (kg).
    pub mass: Vec<f64>,
    /// Physical lumped mass before scaling (kg).
    pub physical_mass: Vec<f64>,
    /// Bitmask of prescribed translation components per node (bit i = axis i).
    pub driven: Vec<u8>,
    /// Time step used (s). This and the four fields below are set by
    /// `crate::solver::stable_step` after assembly (zero before).
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
    /// How the state-driven walls move, stage by stage (`None`: every wall follows its
    /// prescribed history).
    pub stages: Option<crate::boundary::stages::StagePlan>,
    /// Grains, nodes and elements owned (advanced) by this rank: `grains[..owned_grains]`,
    /// nodes `..owned_nodes`, elements `..owned_elements`; the rest are ghosts.
    pub owned_grains: usize,
    pub owned_nodes: usize,
    pub owned_elements: usize,
    /// The periodic cell, when the scene has one.
    pub periodic: Option<periodic::PeriodicCell>,
    /// (ghost grain, owned grain) for every image of an owned grain mirrored here: the
    /// solver copies the owned grain's surface into it, shifted, every step.
    pub local_images: Vec<(usize, usize)>,
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
    /// Range of `State::plastic` holding the plastic state of an owned grain's elements
    /// (`None` for elastic grains and ghosts).
    pub fn plastic_range(&self, grain: usize) -> Option<Range<usize>> {
        let e = self.grains.get(grain)?.elements.clone();
        let first = *self.plastic_slot.get(e.start)?;
        (first != NONE).then(|| first as usize..first as usize + e.len())
    }
    /// Grain owning a model element.
    pub fn grain_of_element(&self, e: usize) -> usize {
        self.grains.partition_point(|g| g.elements.end <= e)
    }
}
