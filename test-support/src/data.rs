//! The shared data directory.

use std::path::{Path, PathBuf};

/// The shared data directory: `$PSR_DATA_DIR`, or `../shared/data` relative to the repository
/// root (this crate lives in `test-support/` under it).
pub fn data_dir() -> PathBuf {
    match std::env::var_os("PSR_DATA_DIR") {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
    }
}

/// The path of a shared data file, or `None` (with a note on stderr) when it is missing, so a
/// test can skip itself on a machine without the data.
pub fn try_data_file(name: &str) -> Option<PathBuf> {
    let path = data_dir().join(name);
    if path.is_file() {
        Some(path)
    } else {
        eprintln!(
            "note: {} not found (set PSR_DATA_DIR); skipping",
            path.display()
        );
        None
    }
}
