//! What the partitioner needs to know about one grain, and how that turns into
//! work per time step.

use serde::{Deserialize, Serialize};

use crate::error::PartitionError;

/// A grain as seen by the partitioner: where it is, how far it reaches, and how
/// big its mesh is. Lengths are in metres (any consistent unit works, as long as
/// the contact margin uses the same one).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GrainInfo {
    /// Centre of the grain's bounding sphere, m.
    pub centre: [f64; 3],
    /// Radius of a sphere around `centre` that contains the whole grain, m.
    pub bounding_radius: f64,
    /// Number of (tetrahedral) elements in the grain's mesh.
    pub elements: usize,
    /// Number of mesh nodes on the grain's surface (the nodes that take part
    /// in contact and are exchanged as ghosts between ranks).
    pub surface_nodes: usize,
}

impl GrainInfo {
    /// Checks that the geometry is usable for neighbour search: a finite
    /// centre and a finite, non-negative bounding radius.
    ///
    /// `index` is only used to name the grain in the error.
    pub fn validate(&self, index: usize) -> Result<(), PartitionError> {
        if self.centre.iter().any(|c| !c.is_finite()) {
            return Err(PartitionError::InvalidGrain {
                grain: index,
                reason: format!("centre {:?} is not finite", self.centre),
            });
        }
        if !self.bounding_radius.is_finite() || self.bounding_radius < 0.0 {
            return Err(PartitionError::InvalidGrain {
                grain: index,
                reason: format!(
                    "bounding radius {} must be finite and non-negative",
                    self.bounding_radius
                ),
            });
        }
        Ok(())
    }

    /// `true` when the geometry can take part in neighbour search
    /// (see [`GrainInfo::validate`]).
    pub(crate) fn has_valid_geometry(&self) -> bool {
        self.centre.iter().all(|c| c.is_finite())
            && self.bounding_radius.is_finite()
            && self.bounding_radius >= 0.0
    }
}

/// Estimated work per explicit time step, in arbitrary "cost units"
/// (1 unit ≈ the internal-force evaluation of one linear tetrahedron).
///
/// Only ratios matter to METIS: the vertex weights balance the work per rank,
/// the edge weights say how expensive it is to separate two touching grains.
///
/// Defaults: 1.0 per element, 4.0 per surface node, 4.0 per expected contact
/// node. The surface-node cost covers contact search, gap evaluation and
/// traction assembly for a node, which is a few element evaluations worth of
/// work; the same price is charged per contact node of a cut edge because that
/// node's data then has to cross a rank boundary and its contact is evaluated
/// against a ghost.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CostModel {
    /// Cost units per mesh element per time step.
    pub cost_per_element: f64,
    /// Cost units per surface node per time step (contact bookkeeping).
    pub cost_per_surface_node: f64,
    /// Cost units per expected contact-zone surface node of a grain pair per
    /// time step; sets the edge weights (see [`crate::GrainGraph::build`]).
    pub cost_per_contact_node: f64,
}

impl Default for CostModel {
    fn default() -> Self {
        Self {
            cost_per_element: 1.0,
            cost_per_surface_node: 4.0,
            cost_per_contact_node: 4.0,
        }
    }
}

impl CostModel {
    /// Work of one grain per time step, in cost units.
    pub fn grain_cost(&self, grain: &GrainInfo) -> f64 {
        self.cost_per_element * grain.elements as f64
            + self.cost_per_surface_node * grain.surface_nodes as f64
    }

    /// Checks that all prices are finite and non-negative.
    pub fn validate(&self) -> Result<(), PartitionError> {
        let prices = [
            ("cost_per_element", self.cost_per_element),
            ("cost_per_surface_node", self.cost_per_surface_node),
            ("cost_per_contact_node", self.cost_per_contact_node),
        ];
        for (name, value) in prices {
            if !value.is_finite() || value < 0.0 {
                return Err(PartitionError::InvalidInput(format!(
                    "cost model: {name} = {value} must be finite and non-negative"
                )));
            }
        }
        Ok(())
    }
}
