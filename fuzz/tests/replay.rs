//! Replays every committed corpus file (`corpus/<target>/`, the seeds and every input a
//! fuzzing run found interesting or failing) through its target, on stable Rust: what CI runs
//! so that a fixed finding stays fixed. A target fails by panicking.

use std::fs;
use std::path::Path;

fn replay(target: &str, run: fn(&[u8])) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("corpus")
        .join(target);
    let mut files: Vec<_> = fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.expect("a directory entry").path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: no corpus to replay", dir.display());
    for file in &files {
        let data = fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        eprintln!("{target}: {}", file.display());
        run(&data);
    }
    eprintln!("{target}: {} inputs replayed", files.len());
}

#[test]
fn ply_reader_corpus() {
    replay("ply_reader", psr_fuzz::ply_reader::run);
}

#[test]
fn c_api_corpus() {
    replay("c_api", psr_fuzz::c_api::run);
}

#[test]
fn reconstruct_corpus() {
    replay("reconstruct", psr_fuzz::reconstruct::run);
}
