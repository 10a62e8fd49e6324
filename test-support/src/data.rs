//! The shared data directory, and the rule for tests that need it: on a developer's machine
//! without the data they skip with a visible message; on CI they fail.

use std::io::Write;
use std::path::{Path, PathBuf};

/// The shared data directory: `$PSR_DATA_DIR`, or `../shared/data` relative to the repository
/// root (this crate lives in `test-support/` under it).
pub fn data_dir() -> PathBuf {
    match std::env::var_os("PSR_DATA_DIR") {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
    }
}

/// True when running on CI: the `CI` environment variable is set to anything but "", "false" or
/// "0" (the same rule as the C++ tests' `inputs::in_ci`).
pub fn in_ci() -> bool {
    std::env::var("CI")
        .map(|v| !v.is_empty() && v != "false" && v != "0")
        .unwrap_or(false)
}

/// The path of the shared data file `name`, for the test named `test`; every test that reads
/// the shared data gets its files through this function.
///
/// When the file is missing: on CI ([`in_ci`]) this panics, so the data cannot silently drop
/// out of the suite; elsewhere it prints `SKIPPED: …` and returns `None`, and the test returns
/// early. The message goes straight to the process's stderr, which the test harness does not
/// capture, so a skipped test is visible in the normal `cargo test` output.
pub fn data_or_skip(name: &str, test: &str) -> Option<PathBuf> {
    let path = data_dir().join(name);
    if path.is_file() {
        return Some(path);
    }
    if in_ci() {
        panic!(
            "{test}: data file {name} not found in {} and CI is set: the shared data must be present \
             on CI (set PSR_DATA_DIR)",
            data_dir().display()
        );
    }
    let _ = writeln!(
        std::io::stderr(),
        "SKIPPED: {test}: {name} not found in {} (set PSR_DATA_DIR to run it)",
        data_dir().display()
    );
    None
}
