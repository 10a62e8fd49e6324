//! `psr`: reconstructs a watertight triangle mesh from a point cloud, oriented or not (the
//! options and the run are the library's, `src/program.rs`).

// Large blocks' pages reused from one stage to the next (src/allocator.rs).
#[cfg(target_os = "linux")]
#[global_allocator]
static ALLOCATOR: psr_cli::allocator::ReusingAllocator = psr_cli::allocator::ReusingAllocator;

fn main() -> std::process::ExitCode {
    psr_cli::main()
}
