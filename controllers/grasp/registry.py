"""Composers by name, as the CLI and experiments ask for them (dm_control ``suite.load`` style).

Learned composers load their models from a directory written by ``python -m controllers.grasp
reproduce --out DIR``, or, by default, from the models shipped in the package
(``controllers/grasp/trained/``, found with importlib.resources, with their provenance).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from controllers.grasp.composition import Composer, KnowledgeBased
from controllers.grasp.errors import GraspError, UnknownNameError
from controllers.grasp.trials import GAIN

#: Composer names: knowledge-based (section 3.6.1), Q-learning (3.6.2), PI with the general
#: predictor (trained on random convex polygons; the default for new shapes), PI with the paper's
#: nine-object predictor (Table 2 (c)) and five-object predictor (Table 2 (d)).
COMPOSERS: tuple[str, ...] = ("kb", "ql", "pi", "pi9", "pi5")
#: Folder of the shipped models inside the package, and their provenance file.
SHIPPED_DIR = "trained"
PROVENANCE_FILE = "provenance.json"


def shipped_model_dir() -> Path:
    """The package's folder of trained models (independent of the current directory)."""
    path = Path(str(resources.files("controllers.grasp").joinpath(SHIPPED_DIR)))
    if not path.is_dir():
        raise GraspError(f"the shipped models are missing ({path}): reinstall graspsim")
    return path


def make_composer(name: str, model_dir: Path | None = None, gain: float = GAIN) -> Composer:
    """The composer called ``name``; learned ones load from ``model_dir`` (default: the shipped
    models), raising ModelNotTrainedError if the file is absent. ``gain`` is the trial runner's
    gain (the PI noise is scaled by it)."""
    if name not in COMPOSERS:
        raise UnknownNameError("controller", name, list(COMPOSERS))
    if name == "kb":
        return KnowledgeBased()
    folder = shipped_model_dir() if model_dir is None else Path(model_dir)
    if name == "ql":
        from controllers.grasp.qlearning import load_ql_composer

        return load_ql_composer(folder)
    from controllers.grasp.preimaging import (
        PI_GENERAL_MODEL_FILE,
        PI_MODEL_FILE,
        PI_SUBSET_MODEL_FILE,
        load_pi_composer,
    )

    files = {"pi": PI_GENERAL_MODEL_FILE, "pi9": PI_MODEL_FILE, "pi5": PI_SUBSET_MODEL_FILE}
    return load_pi_composer(folder, files[name], gain=gain)
