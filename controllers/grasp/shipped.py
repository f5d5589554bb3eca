"""The trained models shipped in the package, their provenance, and a quick check of them.

``controllers/grasp/trained/`` holds the models of one full ``reproduce`` run (its first seed):
the Q-table and the nine-object, five-object and general F/S predictors, with ``provenance.json``
(the command, seed, git commit, date, and the figures the run gave). :func:`check_figures` runs
each learned composer on a small fixed trial set; ``reproduce`` records the result in the
provenance, so anyone can verify that the shipped files still give their recorded figures.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from controllers.grasp.errors import GraspError
from controllers.grasp.objects import PAPER_OBJECTS, paper_object, polygon_set
from controllers.grasp.registry import PROVENANCE_FILE, make_composer, shipped_model_dir
from controllers.grasp.trials import N_CONTACTS, run_trials

#: The fixed check: trials per paper object (member 0) for ql, pi9, pi5; held-out polygons and
#: trials per polygon for pi (the general predictor); the seed of its initial contacts and noise.
CHECK_TRIALS = 20
CHECK_HELDOUT_POLYGONS = 20
CHECK_HELDOUT_TRIALS = 10
CHECK_SEED = 20_260_101
#: Which composers the check covers.
CHECKED = ("ql", "pi", "pi9", "pi5")


def check_figures(model_dir: Path | None = None) -> dict[str, dict]:
    """Failure rate (%), mean S_G and trial count of each learned composer of ``model_dir``
    (default: the shipped models) on the fixed check trials."""
    paper = [paper_object(n) for n in PAPER_OBJECTS]
    held = polygon_set("heldout", CHECK_HELDOUT_POLYGONS)
    out = {}
    for name in CHECKED:
        polys, reps = (held, CHECK_HELDOUT_TRIALS) if name == "pi" else (paper, CHECK_TRIALS)
        idx = np.repeat(np.arange(len(polys)), reps)
        theta0 = np.random.default_rng(CHECK_SEED).uniform(0, 2 * np.pi, (idx.size, N_CONTACTS))
        r = run_trials(
            polys,
            idx,
            make_composer(name, model_dir),
            np.random.default_rng(CHECK_SEED + 1),
            theta_initial=theta0,
        )
        feas = r.s_g[r.feasible]
        out[name] = {
            "trials": int(idx.size),
            "failures": int((~r.success).sum()),
            "failure": 100.0 * r.failure_rate,
            "mean_s_g": float(feas.mean()) if feas.size else float("nan"),
        }
    return out


def read_provenance(model_dir: Path | None = None) -> dict:
    """The provenance of the models in ``model_dir`` (default: the shipped ones)."""
    path = (shipped_model_dir() if model_dir is None else Path(model_dir)) / PROVENANCE_FILE
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise GraspError(f"cannot read the models' provenance {path}: {e}") from e
