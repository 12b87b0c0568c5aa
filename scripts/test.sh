#!/usr/bin/env bash
# Install everything the project needs, then run every check and test: rustfmt, clippy,
# cargo test (core), ruff, mypy (python/hcvt against _core.pyi), pytest (Python API,
# doctests). Exit non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
export OPENBLAS_NUM_THREADS=1

python -m pip install --quiet --disable-pip-version-check -e '.[test]'

echo "== rustfmt";  cargo fmt --all -- --check
echo "== clippy";   cargo clippy --workspace --all-targets --release -- -D warnings
echo "== cargo test"; cargo test --workspace --release
echo "== ruff";     python -m ruff check python tests benchmarks
python -m ruff format --check python tests benchmarks
echo "== mypy";     python -m mypy && python -m mypy.stubtest hcvt._core
echo "== pytest";   python -m pytest python tests
# A miscompilation seen once with one codegen unit (crates/hcvt-core/src/moments.rs,
# FaceMoments::simplex): the Hessian's finite-difference test, built that way too.
echo "== cargo test, one codegen unit"
CARGO_PROFILE_RELEASE_CODEGEN_UNITS=1 cargo test --release -p hcvt-core --test optimise
