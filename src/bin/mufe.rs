//! `mufe` command-line entry point; all logic lives in [`mufe::cli`].
fn main() {
    // Distinct surface shapes may be meshed in `mufe mesh-worker` processes, except in an
    // MPI rank (where starting processes is the launcher's business).
    let launched_by_mpi = ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    if !launched_by_mpi {
        if let Ok(exe) = std::env::current_exe() {
            mufe::mesh::import::enable_worker_processes(exe);
        }
    }
    std::process::exit(mufe::cli::main_with_args(std::env::args_os()));
}
