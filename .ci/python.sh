#!/usr/bin/env bash
# Checks the Python package (python/, distribution psr-poisson, import psr) the way its users
# get it: builds the wheel (which runs cargo for libpsr), installs it into a fresh virtual
# environment and runs python/tests against the installed package, from outside the source
# tree. Also installs `pip install ./python` into a second fresh environment and runs the
# package's example with it, and lints the package (ruff, mypy --strict).
#   1. tools: python3 with venv and pip (apt: python3-venv), strip (binutils);
#   2. the psr program (target/release/psr), which the tests compare meshes with bit for bit;
#   3. pip wheel ./python; a fresh venv; pip install of the wheel and of the test tools
#      (pytest, tqdm, trimesh: the optional integrations are tested too);
#   4. pytest python/tests against the installed wheel (CI=true: tests needing the shared scans
#      fail rather than skip when ../shared/data or $PSR_DATA_DIR is missing);
#   5. pip install ./python into another fresh venv, examples/python/quickstart.py with it;
#   6. ruff and mypy --strict on the package and its tests.
#
#   .ci/python.sh            (KEEP=1 keeps the temporary directory)
set -euo pipefail

script=python.sh
work_prefix=psr-python
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
make_work
cd "$root"

step "tools"
missing=()
command -v python3 >/dev/null || missing+=(python3)
python3 -c "import ensurepip, venv" 2>/dev/null || missing+=(python3-venv)
command -v strip >/dev/null || missing+=(binutils)
[ "${#missing[@]}" -eq 0 ] || apt_install "${missing[@]}"
python3 --version

step "the psr program: cargo build --release -p psr-cli"
cargo build --release -p psr-cli --quiet
export PSR_CLI="$root/target/release/psr"

step "build the wheel: pip wheel ./python"
python3 -m venv "$work/build-env"
"$work/build-env/bin/pip" wheel --quiet --no-deps "$root/python" -w "$work/dist"
wheel="$(ls "$work"/dist/psr_poisson-*.whl)"
ls -l "$wheel"

step "a fresh virtual environment with the wheel, pytest, tqdm and trimesh"
python3 -m venv "$work/venv"
"$work/venv/bin/pip" install --quiet "$wheel" pytest tqdm trimesh
"$work/venv/bin/pip" list 2>/dev/null | grep -E "psr-poisson|numpy|pytest"

step "pytest python/tests against the installed wheel"
# From the work directory, so that nothing from the source tree is importable; conftest.py
# checks that psr comes from the virtual environment (PSR_TEST_INSTALLED).
(cd "$work" && PSR_TEST_INSTALLED=1 "$work/venv/bin/python" -m pytest -p no:cacheprovider \
    -c "$root/python/pyproject.toml" --rootdir "$root/python" "$root/python/tests")

step "pip install ./python into another fresh environment; examples/python/quickstart.py"
python3 -m venv "$work/venv2"
"$work/venv2/bin/pip" install --quiet "$root/python"
(cd "$work" && "$work/venv2/bin/python" "$root/examples/python/quickstart.py" \
    "$root/examples/data/kitten_cgal.ply" "$work/kitten.ply" 7)
[ -s "$work/kitten.ply" ] && [ -s "$work/kitten_trimmed.ply" ] || die "the example wrote no mesh"

step "lints: ruff format --check, ruff check, mypy --strict"
"$work/venv/bin/pip" install --quiet ruff mypy
"$work/venv/bin/ruff" format --check --config "$root/python/pyproject.toml" "$root/python/src" "$root/python/tests" "$root/python/setup.py"
"$work/venv/bin/ruff" check --config "$root/python/pyproject.toml" "$root/python/src" "$root/python/tests" "$root/python/setup.py"
(cd "$root/python" && "$work/venv/bin/python" -m mypy --strict src/psr &&
    MYPYPATH=src "$work/venv/bin/python" -m mypy --strict --ignore-missing-imports tests)

step "the Python package passed"
