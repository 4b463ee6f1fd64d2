//! Grain-level domain decomposition for mufe.
//!
//! Each grain of the granular sample is one vertex of a *grain graph*; two
//! grains are joined by an edge when their bounding spheres come within a
//! contact margin of each other. Vertex weights estimate each grain's work per
//! explicit time step, edge weights the contact work of a pair (see
//! [`CostModel`] and [`GrainGraph::build`]). [`partition`] splits the graph
//! into one part per MPI rank with METIS, balancing work and minimising the
//! weight of cut contacts; [`metrics`] reports balance, cut and the implied
//! ghost (halo) traffic; [`write_partition`] / [`read_partition`] store a
//! partition as text; [`project_step`] projects a step's wall time onto many ranks from a
//! partition's statistics and costs measured on few. [`fcc_packing`] generates regular
//! test samples.
//!
//! The crate is serial and knows nothing about MPI: rank 0 (or an offline
//! tool) computes the partition and the simulator distributes grains by it.
//!
//! ```
//! use partition::{fcc_packing, metrics, partition, CostModel, GrainGraph, GrainInfo};
//!
//! let radius = 1.1e-3; // m
//! let grains: Vec<GrainInfo> = fcc_packing(256, radius)
//!     .into_iter()
//!     .map(|centre| GrainInfo { centre, bounding_radius: radius, elements: 8000, surface_nodes: 1500 })
//!     .collect();
//! let graph = GrainGraph::build(&grains, 0.1 * radius, &CostModel::default());
//! let part = partition(&graph, 4, 0)?;
//! let quality = metrics(&graph, &grains, &part, 4)?;
//! assert!(quality.imbalance < 0.05);
//! println!("{quality}");
//! # Ok::<(), partition::PartitionError>(())
//! ```

mod error;
mod grain;
mod graph;
mod metrics;
mod packing;
mod partition_file;
mod partitioner;
mod projection;
mod rebalance;
#[cfg(test)]
mod test_support;

pub use error::PartitionError;
pub use grain::{CostModel, GrainInfo};
pub use graph::{GrainGraph, EDGE_WEIGHT_RESOLUTION, MAX_TOTAL_WEIGHT, VERTEX_WEIGHT_RESOLUTION};
pub use metrics::{
    metrics, PartitionMetrics, FORWARD_BYTES_PER_GHOST_NODE, HALO_BYTES_PER_GHOST_NODE,
    REVERSE_BYTES_PER_GHOST_NODE,
};
pub use packing::{fcc_block_cells, fcc_packing, MAX_FCC_BLOCK_ASPECT, MAX_FCC_GRAINS};
pub use partition_file::{read_partition, write_partition};
pub use partitioner::{partition, MAX_PARTS_FOR_RECURSIVE_BISECTION};
pub use projection::{project_step, Reduction, StepCosts, StepProjection};
pub use rebalance::BALANCE_TOLERANCE;
