//! Versions: `PSR_VERSION_*` (the header's) and `psr_version*` (the loaded library's), both
//! from the one crate version and checked against Cargo.toml at compile time.

use std::ffi::c_char;

/// Major version of the header you compiled against (the crate version's first number).
/// Compare with psr_version_major() to detect a header/library mismatch.
pub const PSR_VERSION_MAJOR: u32 = 0;
/// Minor version of the header you compiled against.
pub const PSR_VERSION_MINOR: u32 = 1;
/// Patch version of the header you compiled against.
pub const PSR_VERSION_PATCH: u32 = 0;

/// Parses a decimal version component at compile time.
const fn parse_version_component(s: &str) -> u32 {
    let bytes = s.as_bytes();
    let mut value = 0u32;
    let mut i = 0;
    while i < bytes.len() {
        assert!(
            bytes[i].is_ascii_digit(),
            "version component is not a decimal number"
        );
        value = value * 10 + (bytes[i] - b'0') as u32;
        i += 1;
    }
    value
}

// One version source: the crate version. cbindgen can only copy literals into the header, so the
// literals above are checked against Cargo.toml here; bumping the crate version without them
// fails the build.
const _: () = assert!(
    PSR_VERSION_MAJOR == parse_version_component(env!("CARGO_PKG_VERSION_MAJOR")),
    "PSR_VERSION_MAJOR in src/ffi/version.rs disagrees with Cargo.toml: update it and regenerate include/psr.h"
);
const _: () = assert!(
    PSR_VERSION_MINOR == parse_version_component(env!("CARGO_PKG_VERSION_MINOR")),
    "PSR_VERSION_MINOR in src/ffi/version.rs disagrees with Cargo.toml: update it and regenerate include/psr.h"
);
const _: () = assert!(
    PSR_VERSION_PATCH == parse_version_component(env!("CARGO_PKG_VERSION_PATCH")),
    "PSR_VERSION_PATCH in src/ffi/version.rs disagrees with Cargo.toml: update it and regenerate include/psr.h"
);

static VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "\0");

/// The library's version, "MAJOR.MINOR.PATCH", as a static NUL-terminated string (never free
/// it). Never NULL.
#[no_mangle]
pub extern "C" fn psr_version() -> *const c_char {
    VERSION.as_ptr().cast()
}

/// The library's major version. A program compiled against PSR_VERSION_MAJOR.PSR_VERSION_MINOR
/// can check at run time that the library it loaded is ABI-compatible: for 0.x versions the
/// major and minor must both match; from 1.0 on the major must match and the minor be at least
/// the header's.
#[no_mangle]
pub extern "C" fn psr_version_major() -> u32 {
    PSR_VERSION_MAJOR
}

/// The library's minor version (see psr_version_major).
#[no_mangle]
pub extern "C" fn psr_version_minor() -> u32 {
    PSR_VERSION_MINOR
}

/// The library's patch version (see psr_version_major).
#[no_mangle]
pub extern "C" fn psr_version_patch() -> u32 {
    PSR_VERSION_PATCH
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    #[test]
    fn version_parts_match_the_crate_version() {
        // SAFETY: psr_version returns a static NUL-terminated string, never NULL.
        let text = unsafe { CStr::from_ptr(psr_version()) }.to_str().unwrap();
        assert_eq!(text, env!("CARGO_PKG_VERSION"));
        assert_eq!(
            format!(
                "{}.{}.{}",
                psr_version_major(),
                psr_version_minor(),
                psr_version_patch()
            ),
            text
        );
    }
}
