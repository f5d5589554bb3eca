"""The installed wheel works from any folder (issue 13): build graspsim's wheel from a copy of
the source tree, install it with ``--no-deps`` into a fresh virtual environment that sees this
environment's dependencies (a ``.pth`` file naming its site-packages, so nothing is downloaded),
then, from an empty temporary folder with the source tree nowhere on ``sys.path``, load scenes,
build and step a world, and run ``python -m hand_sim.show``, the console scripts and (once package
``fsm`` exists) ``python -m fsm.run --scene clutter3``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
#: The packages that the wheel installs (pyproject.toml, [tool.setuptools.packages.find]).
PACKAGES = (
    "benchmarks",
    "controllers",
    "experiments",
    "fsm",
    "graspsim_base",
    "hand_sim",
    "vision",
)
#: Top-level data folders and where the wheel carries them (hand_sim/resources.py, setup.py).
DATA_FOLDERS = {"models": ("*.xml", "utah_mit_hand/*"), "scenes": ("*.toml",)}
INSTALLED_DATA = "hand_sim/_data"
#: Left out of the copy the wheel is built from: VCS, environments and build or run outputs.
COPY_IGNORE = shutil.ignore_patterns(
    ".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", "*.pyc", "runs", "out", ".*cache"
)
#: Console scripts (pyproject.toml, [project.scripts]) and the ``python -m`` form each stands for,
#: as their --help shows it. graspsim-run is checked with the task cycle.
SCRIPTS = {
    "graspsim-reproduce": "python -m experiments.paper reproduce",
    "graspsim-paper": "python -m experiments.paper",
    "graspsim-physics": "python -m experiments.physics",
    "graspsim-grasp": "python -m controllers.grasp",
    "graspsim-show": "python -m hand_sim.show",
    "graspsim-vision": "python -m vision",
    "graspsim-vision-bench": "python -m vision.bench",
    "graspsim-bench": "python -m experiments.bench",
    "graspsim-interactive": "python -m fsm.interactive",
}
#: Seconds allowed per subprocess (the whole module takes well under a minute on 2 cores).
TIMEOUT = 150
#: Settling: a block of a valid scene moves less than this (m) in this many 2 ms steps.
SETTLE_STEPS, MAX_DRIFT_M = 250, 1e-3


@dataclass(frozen=True)
class Install:
    wheel: Path  #: the built wheel
    python: Path  #: the fresh venv's interpreter
    bin: Path  #: its scripts folder (console scripts)
    site: Path  #: its site-packages, where graspsim is installed
    work: Path  #: empty working folder, outside the source tree
    env: dict[str, str]  #: environment without PYTHONPATH


def run(cmd: list[str | Path], install: Install | None = None, **kw) -> subprocess.CompletedProcess:
    """Run ``cmd``, from the empty work folder when ``install`` is given; fail on non-zero exit."""
    if install is not None:
        kw.setdefault("cwd", install.work)
        kw.setdefault("env", install.env)
    r = subprocess.run(
        [str(c) for c in cmd], capture_output=True, text=True, timeout=TIMEOUT, check=False, **kw
    )
    shown = " ".join(str(c) if len(str(c)) < 200 else "<script>" for c in cmd)
    assert r.returncode == 0, f"{shown}: exit {r.returncode}\n{r.stdout[-999:]}\n{r.stderr[-3000:]}"
    return r


def dependency_paths() -> list[str]:
    """This interpreter's site-packages folders (where graspsim's dependencies are installed)."""
    paths = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    paths |= {p for p in sys.path if Path(p).name in ("site-packages", "dist-packages")}
    return sorted(p for p in paths if Path(p).is_dir() and Path(p).resolve() != REPO)


def data_files_in_source() -> dict[str, Path]:
    """Wheel path -> source file, for every data file that the installed code may read: the
    top-level models/ and scenes/ (carried under hand_sim/_data/) and every non-Python file inside
    the packages (e.g. the shipped trained models in controllers/grasp/trained/)."""
    files = {}
    for folder, patterns in DATA_FOLDERS.items():
        for pattern in patterns:
            for f in (REPO / folder).glob(pattern):
                if f.is_file():
                    rel = f.relative_to(REPO / folder).as_posix()
                    files[f"{INSTALLED_DATA}/{folder}/{rel}"] = f
    for package in PACKAGES:
        for f in (REPO / package).rglob("*"):
            parts = f.relative_to(REPO).parts
            if f.is_file() and f.suffix not in (".py", ".pyc") and "__pycache__" not in parts:
                files[f.relative_to(REPO).as_posix()] = f
    return files


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """graspsim's wheel, built without build isolation from a copy of the source tree (so the
    checkout gets no build/ or egg-info, and a stale one in it cannot leak into the wheel)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(REPO, src, ignore=COPY_IGNORE)
    dist = tmp / "dist"
    pip_wheel = [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-index"]
    run([*pip_wheel, "--no-build-isolation", "-w", dist, src], cwd=tmp)
    (built,) = dist.glob("graspsim-*.whl")
    return built


@pytest.fixture(scope="module")
def install(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Install:
    """A fresh venv with the wheel installed (``--no-deps``) and this environment's site-packages
    on its path through a .pth file, which adds the folders without running their own .pth files
    (so an editable install of the checkout stays invisible)."""
    tmp = tmp_path_factory.mktemp("venv")
    venv = tmp / "venv"
    run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=tmp)
    bin_dir = venv / ("Scripts" if os.name == "nt" else "bin")
    python = bin_dir / ("python.exe" if os.name == "nt" else "python")
    probe = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    site = Path(run([python, "-c", probe], cwd=tmp).stdout.strip())
    (site / "graspsim_test_dependencies.pth").write_text("\n".join(dependency_paths()) + "\n")
    work = tmp / "work"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["MUJOCO_GL"] = os.environ.get("MUJOCO_GL", "egl")
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    # --ignore-installed: the checkout's own (editable) graspsim is visible through the .pth
    # file; it must be neither uninstalled nor taken as already satisfying the wheel.
    pip_install = [python, "-m", "pip", "install", "-q", "--no-deps", "--no-index"]
    run([*pip_install, "--ignore-installed", wheel], cwd=tmp, env=env)
    return Install(wheel, python, bin_dir, site, work, env)


def test_wheel_carries_models_scenes_and_every_data_file(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = data_files_in_source()
    assert {
        f"{INSTALLED_DATA}/models/hand.xml",
        f"{INSTALLED_DATA}/models/utah_mit_hand/utah_mit_hand.xml",
        f"{INSTALLED_DATA}/models/utah_mit_hand/README.md",
        f"{INSTALLED_DATA}/scenes/random.toml",
    } <= set(expected)
    missing = sorted(set(expected) - names)
    assert not missing, f"data files missing from {wheel.name}: {missing}"
    with zipfile.ZipFile(wheel) as z:  # copied unchanged
        for name, src in expected.items():
            assert z.read(name) == src.read_bytes(), name
    top_level = {n.split("/")[0] for n in names if not n.startswith("graspsim-")}
    assert top_level <= set(PACKAGES), f"unexpected top-level entries: {top_level - set(PACKAGES)}"
    assert not any(n.startswith(("models/", "scenes/", "tests/")) for n in names)
    assert "fsm/interactive/page.html" in names  # the interactive page, a package data file


CHECK = r"""
import json, sys
from pathlib import Path
import numpy as np
import benchmarks, controllers, controllers.grasp, hand_sim, vision
from hand_sim.resources import models_dir, scenes_dir
from hand_sim.scene import load_scene, scene_names
from hand_sim.world import World

site, steps = Path(sys.argv[1]).resolve(), int(sys.argv[2])
mods = [benchmarks, controllers, hand_sim, vision]
outside = [m.__name__ for m in mods if not Path(m.__file__).resolve().is_relative_to(site)]
scene = load_scene("clutter3")
rand = load_scene("random", seed=3, blocks=4)
world = World.build(scene)
start = {b.name: world.block_pose(b.name)[0] for b in scene.blocks}
world.step(steps)
drift = max(float(np.linalg.norm(world.block_pose(n)[0] - p)) for n, p in start.items())
tendon = World.build(scene, hand="tendon")
tendon.step(steps)
print(json.dumps({
    "outside_site": outside,
    "models_dir": models_dir().resolve().relative_to(site).as_posix(),
    "scenes_dir": scenes_dir().resolve().relative_to(site).as_posix(),
    "scenes": sorted(scene_names()),
    "clutter3_blocks": sorted(b.name for b in scene.blocks),
    "random_blocks": len(rand.blocks),
    "time": world.time, "drift": drift,
    "tendon_time": tendon.time, "tendon_min_tension": float(tendon.hand_tensions().min()),
}))
"""


def test_installed_wheel_loads_scenes_and_builds_a_world_from_an_empty_folder(
    install: Install,
) -> None:
    out = run([install.python, "-c", CHECK, install.site, SETTLE_STEPS], install).stdout
    r = json.loads(out.strip().splitlines()[-1])
    assert r["outside_site"] == [], "imported from the source tree, not the installed wheel"
    assert r["models_dir"] == f"{INSTALLED_DATA}/models"
    assert r["scenes_dir"] == f"{INSTALLED_DATA}/scenes"
    assert r["scenes"] == sorted(f.stem for f in (REPO / "scenes").glob("*.toml"))
    assert len(r["clutter3_blocks"]) == 3 and r["random_blocks"] == 4
    assert r["time"] == pytest.approx(SETTLE_STEPS * 0.002)
    assert r["tendon_time"] == pytest.approx(SETTLE_STEPS * 0.002)  # the tendon hand ships too
    assert r["tendon_min_tension"] > 0.0
    assert r["drift"] < MAX_DRIFT_M  # the blocks stand still on the table: physics, not just a load


def test_installed_show_runs_from_an_empty_folder(install: Install) -> None:
    out = install.work / "show"
    r = run([install.python, "-m", "hand_sim.show", "--scene", "clutter3", "--out", out], install)
    assert "wrote" in r.stdout
    assert (out / "overhead.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "episode.rrd").stat().st_size > 10_000
    leftovers = {p.name for p in install.work.iterdir()} - {"show"}
    assert not leftovers, f"wrote outside --out: {leftovers}"


@pytest.mark.parametrize("script", sorted(SCRIPTS))
def test_console_script_is_the_python_m_form(install: Install, script: str) -> None:
    r = run([install.bin / script, "--help"], install)
    assert r.stdout.startswith(f"usage: {SCRIPTS[script]}"), r.stdout[:200]


@pytest.mark.e2e
def test_installed_task_cycle_runs_clutter3_from_an_empty_folder(install: Install) -> None:
    run([install.bin / "graspsim-run", "--help"], install)
    run([install.python, "-m", "fsm.run", "--scene", "clutter3"], install)
