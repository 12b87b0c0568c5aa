#!/usr/bin/env bash
# Install everything the project needs (OpenFOAM's checkMesh too), then run every check and
# test: rustfmt, clippy, cargo test (core), ruff, mypy (python/hcvt against _core.pyi),
# pytest (Python API, doctests, the documentation site built with -W and screenshot in a
# headless Chromium). Exit non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=1

pip_() { python -m pip install --quiet --disable-pip-version-check "$@"; }

# One release build of the core, as the wheel users install (abi3, Python >= 3.11). Every
# test below runs against that same wheel, installed here instead of an editable build,
# and tests/test_wheel.py installs it again into a fresh venv with no Rust on PATH.
echo "== wheel (maturin build --release)"
pip_ 'maturin>=1.7,<2'
rm -rf target/wheels
python -m maturin build --release --out target/wheels
wheel=$(ls target/wheels/hcvt-*-abi3-*.whl)
pip_ --force-reinstall --no-deps "$wheel"
pip_ "${wheel}[test,docs]"
export HCVT_WHEEL="$PWD/$wheel" HCVT_REQUIRE_WHEEL=1
# The installed package cannot see ../shared/data from site-packages: name it.
if [ -d ../shared/data ]; then export HCVT_DATA="${HCVT_DATA:-$(cd ../shared/data && pwd)}"; fi

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
# --lib --tests: not the examples (clippy --all-targets checks they build; linking each
# with thin LTO cost minutes); the doc tests separately (cargo cannot mix --doc with them).
echo "== cargo test"; cargo test --workspace --release --lib --tests
cargo test --workspace --release --doc
echo "== ruff";     python -m ruff check python tests benchmarks examples docs/conf.py
python -m ruff format --check python tests benchmarks examples docs/conf.py
echo "== mypy";     python -m mypy && python -m mypy.stubtest hcvt._core
# Doctests from the installed package (--pyargs): the source tree has no compiled core.
echo "== pytest";   python -m pytest --pyargs hcvt tests --durations=25
# A miscompilation was seen once with one codegen unit (crates/hcvt-core/src/moments.rs,
# FaceMoments::simplex, caught by the Hessian's finite-difference test): hcvt-core is now
# built that way by default (Cargo.toml), so every test above runs on such a build.
