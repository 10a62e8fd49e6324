//! Replays every committed input through its target, on stable Rust: what CI runs so that a
//! fixed finding stays fixed. Two directories per target: `corpus/<target>/`, the seeds and
//! what fuzzing found interesting (scripts/fuzz.sh minimises it after each run, so it may drop
//! any file), and `regressions/<target>/`, the inputs of past findings, named for what they
//! found and never minimised away. A target fails by panicking. A regression input replays its
//! finding exactly while the target decodes bytes as it did then (a new choice in an enum of
//! operations changes that; new choices are best read from the input's end), so every finding
//! also has a test of its own in the library's tests, named in the commit that fixed it.

use std::fs;
use std::path::{Path, PathBuf};

/// The files of `dir` in name order (none when it does not exist: not every target has had a
/// finding).
fn inputs(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<_> = entries
        .map(|entry| entry.expect("a directory entry").path())
        .collect();
    files.sort();
    files
}

fn replay(target: &str, run: fn(&[u8])) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let corpus = inputs(&root.join("corpus").join(target));
    assert!(!corpus.is_empty(), "corpus/{target}: no corpus to replay");
    let regressions = inputs(&root.join("regressions").join(target));
    for file in corpus.iter().chain(&regressions) {
        let data = fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        eprintln!("{target}: {}", file.display());
        run(&data);
    }
    eprintln!(
        "{target}: {} corpus and {} regression inputs replayed",
        corpus.len(),
        regressions.len()
    );
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
