"""The build step of the psr-poisson wheel: compile libpsr with cargo and put it in the package.

Why setuptools with a build step rather than maturin or scikit-build-core: the package binds
psr through its C ABI with ctypes, so there is no extension module to compile, only a cdylib to
ship; cargo already builds it (crate-type cdylib), and the one thing the wheel builder must do is
run cargo and copy the library in, which a small build_py step does with the build backend every
pip has. maturin's cffi mode would add cffi as a run-time dependency and generate bindings from
the header at build time; scikit-build-core would go through CMake for the same cargo call.

Environment:
  PSR_LIBRARY   use this prebuilt libpsr.so instead of running cargo (it must come from the same
                commit, e.g. target/release/libpsr.so after `cargo build --release`).
  CARGO         the cargo to run (default: cargo on PATH, then ~/.cargo/bin/cargo).
The library is stripped of debug info (when `strip` is available) so the wheel stays small.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

try:
    from setuptools.command.bdist_wheel import bdist_wheel
except ImportError:  # setuptools < 70.1
    from wheel.bdist_wheel import bdist_wheel  # type: ignore[no-redef]

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
LIB_NAME = {"darwin": "libpsr.dylib", "win32": "psr.dll"}.get(sys.platform, "libpsr.so")


def crate_version() -> str:
    """The workspace version in ../Cargo.toml: the package has the library's version."""
    cargo_toml = REPO / "Cargo.toml"
    if not cargo_toml.exists():
        raise SystemExit(
            "psr-poisson builds from the psr repository (it needs ../Cargo.toml and the Rust "
            "sources): run `pip install ./python` or `pip wheel ./python` from a checkout"
        )
    section = ""
    for line in cargo_toml.read_text().splitlines():
        if line.startswith("["):
            section = line.strip()
        m = re.match(r'version\s*=\s*"([^"]+)"', line)
        if m and section == "[workspace.package]":
            return m.group(1)
    raise SystemExit("no version in [workspace.package] of Cargo.toml")


def cargo() -> str:
    found = os.environ.get("CARGO") or shutil.which("cargo")
    home = Path(os.environ.get("CARGO_HOME", Path.home() / ".cargo")) / "bin" / "cargo"
    if found:
        return found
    if home.exists():
        return str(home)
    raise SystemExit("cargo not found: install Rust (https://rustup.rs) or set PSR_LIBRARY")


def build_library() -> Path:
    """Builds libpsr with cargo (release profile) and returns the cdylib's path."""
    prebuilt = os.environ.get("PSR_LIBRARY")
    if prebuilt:
        path = Path(prebuilt)
        if not path.is_file():
            raise SystemExit(f"PSR_LIBRARY={prebuilt} is not a file")
        return path
    cmd = [
        cargo(),
        "build",
        "--release",
        "--lib",
        "-p",
        "psr",
        "--message-format=json-render-diagnostics",
        "--manifest-path",
        str(REPO / "Cargo.toml"),
    ]
    print("psr-poisson: " + " ".join(cmd), flush=True)
    run = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, check=False)
    if run.returncode != 0:
        raise SystemExit(f"cargo build failed (exit {run.returncode})")
    for line in run.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg["target"]["name"] == "psr":
            for f in msg.get("filenames", []):
                if Path(f).name == LIB_NAME:
                    return Path(f)
    raise SystemExit(f"cargo built no {LIB_NAME}")


class BuildPyWithLibrary(build_py):
    """build_py, then libpsr copied into the package directory of the build."""

    def run(self) -> None:
        super().run()
        source = build_library()
        target = Path(self.build_lib) / "psr" / LIB_NAME
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, target)
        strip = shutil.which("strip")
        if strip and sys.platform.startswith("linux"):
            subprocess.run([strip, "--strip-debug", str(target)], check=True)
        print(f"psr-poisson: {source} -> {target}", flush=True)


class BinaryDistribution(Distribution):
    """The wheel holds a native library: platform-specific, though no extension module."""

    def has_ext_modules(self) -> bool:
        return True


class PlatformWheel(bdist_wheel):
    """py3-none-<platform>: any Python 3 (ctypes, no C-API use), one platform."""

    def finalize_options(self) -> None:
        super().finalize_options()
        self.root_is_pure = False

    def get_tag(self) -> tuple[str, str, str]:
        _, _, platform = super().get_tag()
        return "py3", "none", platform


setup(
    version=crate_version(),
    distclass=BinaryDistribution,
    cmdclass={"build_py": BuildPyWithLibrary, "bdist_wheel": PlatformWheel},
)
