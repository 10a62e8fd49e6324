//! `psr`: reconstructs a watertight triangle mesh from a point cloud, oriented or not (the
//! options and the run are the library's, `src/program.rs`).

fn main() -> std::process::ExitCode {
    psr_cli::main()
}
