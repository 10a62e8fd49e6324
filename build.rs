//! Sets the shared library's SONAME by cargo-c's rule, so that programs linked against
//! libpsr.so record the ABI they were built for: `libpsr.so.MAJOR` from 1.0 on,
//! `libpsr.so.0.MINOR` for 0.x (every 0.x minor may break the ABI), `libpsr.so.0.0.PATCH` for
//! 0.0.x. Nothing else belongs here.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("linux") {
        return;
    }
    let part = |name: &str| std::env::var(name).expect("cargo sets the version variables");
    let (major, minor, patch) = (
        part("CARGO_PKG_VERSION_MAJOR"),
        part("CARGO_PKG_VERSION_MINOR"),
        part("CARGO_PKG_VERSION_PATCH"),
    );
    let abi = match (major.as_str(), minor.as_str()) {
        ("0", "0") => format!("0.0.{patch}"),
        ("0", _) => format!("0.{minor}"),
        _ => major,
    };
    println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libpsr.so.{abi}");
}
