//! Writes into the shared library the name the loader should look for, when the build asks for
//! one through `PSR_SONAME` (CMakeLists.txt does: it is the one place where cargo-c's rule
//! turns the crate version into that name, e.g. `libpsr.so.0.1`). ELF systems get it as the
//! SONAME, Apple systems as the install name `@rpath/<name>`; Windows DLLs have neither.
//!
//! A plain `cargo build` sets no PSR_SONAME and gets an unversioned library, as for any cdylib
//! (cargo-c, if used, applies the same rule itself). Nothing else belongs here.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=PSR_SONAME");
    let name = std::env::var("PSR_SONAME").unwrap_or_default();
    if name.is_empty() {
        return;
    }
    assert!(
        !name.contains([',', ' ', '\t', '\n', '/']),
        "PSR_SONAME must be a plain file name such as libpsr.so.0.1, got {name:?}"
    );
    let family = std::env::var("CARGO_CFG_TARGET_FAMILY").unwrap_or_default();
    let vendor = std::env::var("CARGO_CFG_TARGET_VENDOR").unwrap_or_default();
    if vendor == "apple" {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-install_name,@rpath/{name}");
    } else if family.split(',').any(|f| f == "unix") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,{name}");
    }
}
