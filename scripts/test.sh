#!/usr/bin/env bash
# Install everything the project needs (OpenFOAM's checkMesh too), then run every check and
# test: rustfmt, clippy, cargo test (core), ruff, mypy (python/hcvt against _core.pyi),
# pytest (Python API, doctests, the documentation site built with -W and screenshot in a
# headless Chromium). Exit non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=1

python -m pip install --quiet --disable-pip-version-check -e '.[test,docs]'

# OpenFOAM's checkMesh judges the meshes hcvt writes (tests/test_export.py): Debian's
# package (OpenFOAM 1912), installed when missing; its tools need WM_PROJECT_DIR.
if ! command -v checkMesh > /dev/null; then
    echo "== installing OpenFOAM (apt-get install openfoam)"
    sudo_=""
    if [ "$(id -u)" -ne 0 ]; then sudo_="sudo"; fi
    $sudo_ apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq openfoam > /dev/null
fi
export WM_PROJECT_DIR="${WM_PROJECT_DIR:-/usr/share/openfoam}"
export HCVT_REQUIRE_CHECKMESH=1  # the OpenFOAM tests fail, not skip, without it

# A headless Chromium for the documentation's screenshots (tests/test_docs.py), driven by
# Playwright from PyPI; Debian's build, since Playwright's own download is not reachable.
if ! command -v chromium-headless-shell > /dev/null && ! command -v chromium > /dev/null; then
    echo "== installing chromium-headless-shell (apt-get)"
    sudo_=""
    if [ "$(id -u)" -ne 0 ]; then sudo_="sudo"; fi
    $sudo_ apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq chromium-headless-shell > /dev/null
fi
export HCVT_REQUIRE_BROWSER=1  # the screenshot test fails, not skips, without one

echo "== rustfmt";  cargo fmt --all -- --check
echo "== clippy";   cargo clippy --workspace --all-targets --release -- -D warnings
echo "== cargo test"; cargo test --workspace --release
echo "== ruff";     python -m ruff check python tests benchmarks examples docs/conf.py
python -m ruff format --check python tests benchmarks examples docs/conf.py
echo "== mypy";     python -m mypy && python -m mypy.stubtest hcvt._core
echo "== pytest";   python -m pytest python tests
# A miscompilation seen once with one codegen unit (crates/hcvt-core/src/moments.rs,
# FaceMoments::simplex): the Hessian's finite-difference test, built that way too.
echo "== cargo test, one codegen unit"
CARGO_PROFILE_RELEASE_CODEGEN_UNITS=1 cargo test --release -p hcvt-core --test optimise
