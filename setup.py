"""Build step of graspsim's wheel (the metadata is in pyproject.toml).

The MJCF models and scene files stay in the top-level folders ``models/`` and ``scenes/`` of the
checkout; a wheel carries them inside the ``hand_sim`` package as ``hand_sim/_data/<folder>/``,
where :mod:`hand_sim.resources` looks first. Editable installs read the checkout's folders, so
nothing is copied for them.
"""

from __future__ import annotations

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
#: Top-level data folder -> file patterns copied into the wheel, keeping their subfolders (see
#: hand_sim/resources.py): the MJCF models, the tendon-driven hand's folder (its model, scene and
#: README), the scene files.
DATA_FOLDERS = {"models": ("*.xml", "utah_mit_hand/*"), "scenes": ("*.toml",)}
#: Where they go inside the built package tree.
INSTALLED_DATA = Path("hand_sim", "_data")


def data_files() -> list[tuple[Path, Path]]:
    """(source file, destination relative to the build folder) for every data file."""
    pairs = []
    for folder, patterns in DATA_FOLDERS.items():
        for pattern in patterns:
            files = sorted(f for f in (ROOT / folder).glob(pattern) if f.is_file())
            if not files:
                raise SystemExit(
                    f"setup.py: no {pattern} in {ROOT / folder}; is this a full checkout?"
                )
            pairs += [(f, INSTALLED_DATA / folder / f.relative_to(ROOT / folder)) for f in files]
    return pairs


class BuildPyWithData(build_py):
    """``build_py`` that also copies ``models/`` and ``scenes/`` into ``hand_sim/_data/``."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        for src, rel in data_files():
            dst = Path(self.build_lib) / rel
            self.mkpath(str(dst.parent))
            self.copy_file(str(src), str(dst))

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        outputs = super().get_outputs(include_bytecode)
        if getattr(self, "editable_mode", False):
            return outputs
        return outputs + [str(Path(self.build_lib) / rel) for _, rel in data_files()]


setup(cmdclass={"build_py": BuildPyWithData})
