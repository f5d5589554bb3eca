"""Composers by name, as the CLI and experiments ask for them (dm_control ``suite.load`` style)."""

from __future__ import annotations

from pathlib import Path

from controllers.grasp.composition import Composer, KnowledgeBased
from controllers.grasp.errors import UnknownNameError

#: Composer names the CLI accepts: knowledge-based (section 3.6.1), Q-learning (3.6.2),
#: pre-imaging (section 4).
COMPOSERS: tuple[str, ...] = ("kb",)

#: Where trained models are kept unless told otherwise.
DEFAULT_MODEL_DIR = Path("models_trained")


def make_composer(name: str, model_dir: Path = DEFAULT_MODEL_DIR) -> Composer:
    """The composer called ``name``; learned ones are loaded from ``model_dir``."""
    if name == "kb":
        return KnowledgeBased()
    raise UnknownNameError("controller", name, list(COMPOSERS))
