"""Wheels without Rust (issue 31): the abi3 wheel installs and runs where no toolchain is.

``scripts/test.sh`` builds the wheel once (``maturin build --release``), installs that
same wheel for every other test, and passes its path here as ``HCVT_WHEEL``: the wheel
these tests install is the one the suite tested, and no extra build of the core is made.
Here it goes into a fresh virtual environment (no system site-packages, dependencies as
wheels from the package index) whose PATH holds no ``cargo`` or ``rustc``, and the
README's main job runs from it. Without ``HCVT_WHEEL`` the tests are skipped, unless
``HCVT_REQUIRE_WHEEL=1`` (set by ``scripts/test.sh``), where they fail.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
import time
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
WHEEL = os.environ.get("HCVT_WHEEL")

if not WHEEL:
    if os.environ.get("HCVT_REQUIRE_WHEEL") == "1":
        pytest.fail("HCVT_REQUIRE_WHEEL=1 but no HCVT_WHEEL", pytrace=False)
    pytest.skip("no HCVT_WHEEL: scripts/test.sh builds one", allow_module_level=True)


def path_without_rust() -> str:
    """The current PATH less every folder that holds cargo or rustc."""
    keep = []
    for folder in os.environ.get("PATH", "").split(os.pathsep):
        if folder and not any(
            (Path(folder) / tool).exists() for tool in ("cargo", "rustc", "rustup")
        ):
            keep.append(folder)
    return os.pathsep.join(keep)


def test_the_wheel_is_abi3_with_the_compiled_core() -> None:
    wheel = Path(WHEEL)
    assert wheel.name.startswith("hcvt-") and "-abi3-" in wheel.name, wheel.name
    names = zipfile.ZipFile(wheel).namelist()
    assert any(n.startswith("hcvt/_core") and n.endswith(".so") for n in names), names
    for needed in ("hcvt/__init__.py", "hcvt/_core.pyi", "hcvt/py.typed", "hcvt/accessor.py"):
        assert needed in names, needed
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    text = zipfile.ZipFile(wheel).read(entry_points).decode().replace(" ", "")
    assert "[pyvista.accessors]\nhcvt=hcvt.accessor" in text, text
    assert "[console_scripts]\nhcvt=hcvt.cli:main" in text, text


def test_wheel_runs_the_readme_job_without_a_rust_toolchain(tmp_path: Path) -> None:
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CARGO", "RUSTUP"))}
    env.pop("PYTHONPATH", None)
    env["PATH"] = os.pathsep.join([str(venv / "bin"), path_without_rust()])
    env["VIRTUAL_ENV"] = str(venv)
    env["MPLBACKEND"] = "Agg"
    for tool in ("cargo", "rustc"):
        assert shutil.which(tool, path=env["PATH"]) is None, f"{tool} is on the test's PATH"
    start = time.perf_counter()
    install = subprocess.run(
        [str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet",
         "--disable-pip-version-check", "--only-binary=:all:", WHEEL],
        env=env, capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    seconds = time.perf_counter() - start
    assert install.returncode == 0, install.stderr[-4000:]
    print(f"pip install of the wheel and its dependencies into a fresh venv: {seconds:.1f} s")
    where = subprocess.run(
        [str(venv / "bin" / "python"), "-c", "import hcvt; print(hcvt.__file__)"],
        env=env, cwd=tmp_path, capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert Path(where.stdout.strip()).is_relative_to(venv), where.stdout
    done = subprocess.run(
        [str(venv / "bin" / "hcvt"), "run", "star", "-n", "2000", "--plot", "star.png"],
        env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-4000:]
    picture = tmp_path / "star.png"
    assert picture.read_bytes().startswith(b"\x89PNG") and picture.stat().st_size > 50_000


def test_the_sdist_builds(tmp_path: Path) -> None:
    # scripts/test.sh installs maturin into this Python to build the wheel.
    maturin = [sys.executable, "-m", "maturin"]
    if subprocess.run([*maturin, "--version"], capture_output=True).returncode != 0:
        found = shutil.which("maturin")
        if found is None:
            pytest.fail("no maturin in this Python nor on PATH")
        maturin = [found]
    done = subprocess.run(
        [*maturin, "sdist", "--out", str(tmp_path)], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-4000:]
    (sdist,) = tmp_path.glob("hcvt-*.tar.gz")
    names = tarfile.open(sdist).getnames()
    top = names[0].split("/")[0]
    for needed in ("pyproject.toml", "Cargo.toml", "crates/hcvt-core/src/lib.rs",
                   "crates/hcvt-py/src/lib.rs", "python/hcvt/__init__.py"):  # fmt: skip
        assert f"{top}/{needed}" in names, needed
