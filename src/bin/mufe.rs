//! `mufe` command-line entry point; all logic lives in [`mufe::cli`].
fn main() {
    // Distinct surface shapes may be meshed in `mufe mesh-worker` processes, except in an
    // MPI rank (where starting processes is the launcher's business).
    if !mufe::domain::launched_by_mpi_launcher() {
        if let Ok(exe) = std::env::current_exe() {
            mufe::mesh::import::enable_worker_processes(exe);
        }
    }
    std::process::exit(mufe::cli::main_with_args(std::env::args_os()));
}
