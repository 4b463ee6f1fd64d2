//! Output: the parallel HDF5 results file (`results.h5`), the collective-write layer
//! under it, and PNG line plots ([`plot`]) shared by runs and `mufe
//! validate`. Later: XDMF for ParaView, checkpoints and restart.
//!
//! MPI itself stays in [`crate::domain`]; this module only hands the Domain's communicator
//! to HDF5's MPI-IO driver and relies on the Domain's collectives to keep ranks in step.

pub mod checkpoint;
pub mod collective;
pub mod energy_figures;
pub mod plot;
pub mod provenance;
pub mod results;

pub use collective::IoMode;
pub use results::{
    grain_row_blocks, FieldPart, HistoryColumn, IoCount, IoStats, MeshPart, Provenance,
    ResultsWriter, RESULTS_FILE_NAME,
};
pub mod xdmf;
