"""Composers by name, as the CLI and experiments ask for them (dm_control ``suite.load`` style)."""

from __future__ import annotations

from pathlib import Path

from controllers.grasp.composition import Composer, KnowledgeBased
from controllers.grasp.errors import UnknownNameError
from controllers.grasp.trials import GAIN

#: Composer names the CLI accepts: knowledge-based (section 3.6.1), Q-learning (3.6.2),
#: pre-imaging (section 4, predictor trained on all nine objects).
COMPOSERS: tuple[str, ...] = ("kb", "ql", "pi")

#: Where trained models are kept unless told otherwise.
DEFAULT_MODEL_DIR = Path("models_trained")


def make_composer(name: str, model_dir: Path = DEFAULT_MODEL_DIR, gain: float = GAIN) -> Composer:
    """The composer called ``name``; learned ones are loaded from ``model_dir`` (written by
    ``python -m controllers.grasp reproduce --out DIR``), raising ModelNotTrainedError if absent.
    ``gain`` is the trial runner's gain (the PI noise is scaled by it)."""
    if name == "kb":
        return KnowledgeBased()
    if name == "ql":
        from controllers.grasp.qlearning import load_ql_composer

        return load_ql_composer(Path(model_dir))
    if name == "pi":
        from controllers.grasp.preimaging import load_pi_composer

        return load_pi_composer(Path(model_dir), gain=gain)
    raise UnknownNameError("controller", name, list(COMPOSERS))
