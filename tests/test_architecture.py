"""The house rules of docs/contributor_guide.md, checked on the code as it is: the layers contract
(``lint-imports``, import-linter, with the contracts of pyproject.toml) is kept, an import that
goes up a layer breaks it, and no module is over 500 lines."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: The packages of the layers contract, bottom first (pyproject.toml, [tool.importlinter]).
LAYERED = ("graspsim_base", "controllers", "hand_sim", "vision", "fsm", "experiments")
#: Every folder of Python code the 500-line rule covers.
CODE = (*LAYERED, "benchmarks", "tools", "tests")
MAX_MODULE_LINES = 500
CONTRACTS = {
    "layers",
    "controllers",
    "no-circles",
    "experiments-apart",
    "grasp-core-pure",
    "base-small",
}
#: controllers/' sub-packages by role, top first (each a layer of the "controllers" contract).
CONTROLLER_LAYERS = ("preshape", "deliver", "hand", "reach", "posture", "planning")
#: The most modules controllers/ holds at its top level (the rest are in its sub-packages).
MAX_CONTROLLERS_TOP_MODULES = 8


def lint_imports(root: Path) -> subprocess.CompletedProcess[str]:
    """``lint-imports`` on the tree at ``root`` (its pyproject.toml, its packages first on the
    path), without the cache."""
    exe = Path(sys.executable).with_name("lint-imports")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "importlinter.cli"]
    return subprocess.run(
        [*cmd, "--no-cache"],
        cwd=root,
        env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(root)},
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_the_contracts_are_the_documented_ones() -> None:
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["importlinter"]
    assert set(config["root_packages"]) == set(LAYERED)
    assert {c["id"] for c in config["contracts"]} == CONTRACTS
    layers = next(c for c in config["contracts"] if c["id"] == "layers")["layers"]
    assert [layer.split(" ")[0] for layer in layers] == [
        "experiments",
        "fsm",
        *(f"controllers.{name}" for name in CONTROLLER_LAYERS),
        "controllers.errors",
        "vision",
        "hand_sim",
        "controllers.grasp",
        "graspsim_base",
    ]
    inner = next(c for c in config["contracts"] if c["id"] == "controllers")["layers"]
    assert [layer.split(" ")[0] for layer in inner] == [*CONTROLLER_LAYERS, "errors", "grasp"]


def test_controllers_keeps_its_modules_in_sub_packages() -> None:
    top = sorted(p.name for p in (REPO / "controllers").glob("*.py"))
    assert len(top) <= MAX_CONTROLLERS_TOP_MODULES, top
    packages = {p.parent.name for p in (REPO / "controllers").glob("*/__init__.py")}
    assert packages == {*CONTROLLER_LAYERS, "grasp"}


def test_the_layers_contract_is_kept() -> None:
    r = lint_imports(REPO)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert f"Contracts: {len(CONTRACTS)} kept, 0 broken." in r.stdout


@pytest.fixture(scope="module")
def tree_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The layered packages and pyproject.toml, copied (sources only)."""
    root = tmp_path_factory.mktemp("house")
    shutil.copy(REPO / "pyproject.toml", root)
    for package in LAYERED:
        shutil.copytree(
            REPO / package, root / package, ignore=shutil.ignore_patterns("*.pyc", "__pycache__")
        )
    return root


@pytest.mark.parametrize(
    ("module", "line", "contract"),
    [
        ("controllers/grasp/score.py", "import fsm.run", "Each folder one layer"),
        ("hand_sim/geometry.py", "from vision import analyze", "Each folder one layer"),
        ("controllers/grasp/wrench.py", "import mujoco", "The grasp core is mathematics"),
        ("experiments/paper/tables.py", "import experiments.bench.stats", "do not depend on one"),
        ("controllers/hand/grip.py", "import controllers.preshape.moves", "controllers/ by role"),
        ("controllers/reach/coarse.py", "import controllers.deliver.plan", "Each folder one layer"),
        ("controllers/grasp/polygon.py", "import controllers.grasp.atomic", "No import circle"),
    ],
)
def test_an_import_against_the_layers_breaks_the_contract(
    tree_copy: Path, module: str, line: str, contract: str
) -> None:
    path = tree_copy / module
    original = path.read_text()
    path.write_text(original + f"\n{line}  # noqa\n")
    try:
        r = lint_imports(tree_copy)
    finally:
        path.write_text(original)
    assert r.returncode == 1, r.stdout[-2000:]
    assert f"{contract}" in r.stdout and "BROKEN" in r.stdout


def test_a_controllers_module_outside_the_contract_breaks_it(tree_copy: Path) -> None:
    extra = tree_copy / "controllers" / "unplaced.py"
    extra.write_text('"""A controller nobody put in a layer."""\n')
    try:
        r = lint_imports(tree_copy)
    finally:
        extra.unlink()
    assert r.returncode == 1 and "unplaced" in r.stdout


def test_no_module_is_over_500_lines() -> None:
    long = {
        str(p.relative_to(REPO)): n
        for folder in CODE
        for p in (REPO / folder).rglob("*.py")
        if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_an_episode_imports_neither_torch_nor_glfw() -> None:
    """Start-up cost: torch (about 3 s to import) serves only the predictor's training; the task
    cycle with the learned (pi) controller evaluates the trained predictor in numpy. And with
    no ``MUJOCO_GL`` set (as from a plain shell), the task cycle's modules choose EGL before
    MuJoCo is first imported: MuJoCo never loads GLFW (a display library, 0.2-0.4 s)."""
    code = (
        "import sys\n"
        "import fsm.machine, fsm.run, fsm.recording\n"
        "from controllers.grasp.registry import make_composer\n"
        "make_composer('pi'); make_composer('ql'); make_composer('kb')\n"
        "print(sorted(m for m in sys.modules\n"
        "             if m in ('torch', 'glfw') or m.startswith('torch.')))\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO,
        env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(REPO)},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == "[]"
