//! `mufe` command-line entry point; all logic lives in [`mufe::cli`].
fn main() {
    std::process::exit(mufe::cli::main_with_args(std::env::args_os()));
}
