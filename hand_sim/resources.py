"""Where graspsim's data files are: the MJCF models (``models/*.xml`` and the tendon-driven hand's
folder ``models/utah_mit_hand/``) and the scene files (``scenes/*.toml``, including the random
generator's defaults ``scenes/random.toml``).

In a checkout (and an editable install) they are the top-level folders ``models/`` and ``scenes/``
beside the packages. A wheel cannot hold top-level data folders without spilling generic names into
site-packages, so the build step in ``setup.py`` copies them into the package, as
``hand_sim/_data/models`` and ``hand_sim/_data/scenes``. Both places are found relative to this
package (:mod:`importlib.resources`), never through the current directory, so the world builds
from any folder, a notebook's included.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from hand_sim.errors import HandSimError

#: Sub-package folder that holds the data folders in an installed wheel (written by setup.py).
INSTALLED_DATA = "_data"
#: The data folders: the MJCF models and the scene files.
MODELS, SCENES = "models", "scenes"
DATA_FOLDERS = (MODELS, SCENES)
#: A checkout is recognised by this file beside the packages.
CHECKOUT_MARKER = "pyproject.toml"


class DataNotFoundError(HandSimError, FileNotFoundError):
    """A data folder of graspsim is missing: the installation is incomplete."""


def _package_root() -> Path:
    """The folder of the installed (or checked-out) ``hand_sim`` package."""
    root = resources.files("hand_sim")
    if not isinstance(root, Path):
        raise DataNotFoundError(
            f"hand_sim is imported from {root}, not from a folder: install graspsim "
            "with pip (unpacked) so that MuJoCo can read its model files"
        )
    return root


def candidates(name: str) -> tuple[Path, Path]:
    """The two places data folder ``name`` may be: the installed copy inside the package, then
    the checkout's top-level folder."""
    if name not in DATA_FOLDERS:
        raise ValueError(f"unknown data folder {name!r}; valid: {', '.join(DATA_FOLDERS)}")
    package = _package_root()
    return package / INSTALLED_DATA / name, package.parent / name


def data_dir(name: str) -> Path:
    """Data folder ``name`` (``"models"`` or ``"scenes"``) as an absolute path.

    The installed copy wins; a top-level folder counts only in a checkout (``pyproject.toml``
    beside it), so an unrelated ``models/`` in site-packages is never picked up.
    Raises :class:`DataNotFoundError` naming both places when neither exists.
    """
    installed, checkout = candidates(name)
    if installed.is_dir():
        return installed
    if checkout.is_dir() and (checkout.parent / CHECKOUT_MARKER).is_file():
        return checkout
    raise DataNotFoundError(
        f"graspsim's {name}/ folder is missing (looked in {installed} and {checkout}): "
        "reinstall graspsim from its wheel or checkout (pip install --force-reinstall ...)"
    )


def models_dir() -> Path:
    """Folder of the MJCF models (hand.xml, arm.xml, table.xml, hand_scene.xml)."""
    return data_dir(MODELS)


def scenes_dir() -> Path:
    """Folder of the scene files (``<name>.toml``) and the random generator's ``random.toml``."""
    return data_dir(SCENES)
