"""The experiments of ``python -m experiments.paper reproduce``, one task each (one experiment of
one seed): Q-learning (section 3.6.2), Tables 1 and 2 with the pre-image noise readings (section
4), the general F/S predictor on random polygons, the atomic-action controller (section 2) and
the failure curves; the run's configuration and the seeded random streams they draw from."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from controllers.grasp.atomic import (
    ATOMIC_EPOCHS,
    ATOMIC_TRIALS,
    TEST_ROTATION_DEG,
    TEST_TRIALS,
    ScoreTable,
    evaluate_atomic,
    train_atomic,
)
from controllers.grasp.composition import Composer, KnowledgeBased
from controllers.grasp.objects import (
    FAMILY_SIZE,
    PAPER_OBJECTS,
    ObjectSet,
    paper_object,
    polygon_set,
)
from controllers.grasp.predictor import PREDICTOR_EPOCHS
from controllers.grasp.predictor_training import train_predictor
from controllers.grasp.preimaging import (
    NOISE_READINGS,
    PreImaging,
)
from controllers.grasp.qlearning import (
    EPOCHS,
    TRIALS_PER_OBJECT,
    QLearningComposer,
    train_qlearning,
)
from controllers.grasp.trials import N_CONTACTS, PolygonBatch, TrialBatch, run_trials
from experiments.paper.tables import (
    FAMILY_TRIALS,
    TrialSet,
    object_rows,
    trial_set,
)
from experiments.paper.tables import TEST_TRIALS as TABLE_TRIALS

#: Table 2 of the paper: PI trained on all nine objects (c) and on five of them (d), failure (%).
PAPER_TABLE2_PI_ALL: dict[str, float] = {
    "triangle": 0.00, "square": 0.00, "pentagon": 0.00, "hexagon": 0.00,
    "irregular_triangle": 2.50, "rectangle": 0.00, "trapezoid": 0.50,
    "irregular_pentagon": 0.00, "irregular_hexagon": 0.00,
}  # fmt: skip
PAPER_TABLE2_PI_FIVE: dict[str, float] = {
    "triangle": 1.00, "square": 0.00, "pentagon": 0.00, "hexagon": 0.00,
    "irregular_triangle": 2.50, "rectangle": 0.00, "trapezoid": 0.00,
    "irregular_pentagon": 0.50, "irregular_hexagon": 0.00,
}  # fmt: skip
PAPER_TABLE2_AVERAGE = {"kb": 10.06, "ql": 8.33, "pi": 0.33, "pi5": 0.44}
#: Mean grasp score over the objects (section 4.5).
PAPER_MEAN_SG = {"kb": 0.172, "ql": 0.189, "pi": 0.138}
#: The five objects of Table 2 (d).
FIVE_OBJECTS: tuple[str, ...] = (
    "triangle", "square", "trapezoid", "irregular_pentagon", "irregular_hexagon",
)  # fmt: skip
#: Seeds of a default run: tables are means and standard deviations over them.
DEFAULT_SEEDS: tuple[int, ...] = (0, 1, 2)
#: Epochs per batch when running the (non-learning) KB and PI failure curves.
CURVE_CHUNK = 10
#: Trials on the square for Figures 10 and 11.
FIGURE10_TRIALS = 200
#: Noise scales of the sensitivity sweep (literal reading; 1 = the paper's noise as radians).
NOISE_SCALES: tuple[float, ...] = (2.0, 4.0, 6.0)
#: The general PI controller (beyond the paper): F/S predictor trained on random convex polygons
#: (``polygon_set("train")``), noise read as a fraction of a turn, failure predicted when the
#: output exceeds -0.5; every run reports the validation polygons' table and the setting with
#: threshold 0 beside it.
#: Chosen on the validation polygons: docs/findings.md, "General predictor's reading and threshold".
GENERAL_SETTINGS = {"reading": "turn", "threshold": -0.5}
#: Knowledge-based training trials per epoch of the general predictor (each on a new polygon).
GENERAL_TRIALS_PER_EPOCH = 90
#: Independent random streams of one seed (SeedSequence children), each used for one purpose.
STREAMS = {
    name: i
    for i, name in enumerate(
        (
            "ql", "pi9", "pi5", "test", "test_noise", "kb_curve", "pi_curve", "atomic",
            "atomic_test", "general", "fig10", "fig10_noise", "heldout", "heldout_noise",
            "validation", "validation_noise",
        )
    )
}  # fmt: skip
CONTROLLER_LABELS = {
    "kb": "Knowledge-based (a)",
    "ql": "Q-learning (b)",
    "pi": "PI, 9 objects (c)",
    "pi5": "PI, 5 objects (d)",
}
Progress = Callable[[str], None]


@dataclass(frozen=True)
class ReproduceConfig:
    """Experiment sizes; :meth:`paper` is the paper's, :meth:`quick_run` a reduced one for CI."""

    seeds: tuple[int, ...] = DEFAULT_SEEDS
    workers: int = 2
    ql_epochs: int = EPOCHS
    trials_per_object: int = TRIALS_PER_OBJECT
    predictor_epochs: int = PREDICTOR_EPOCHS
    test_trials: int = TABLE_TRIALS
    family_size: int = FAMILY_SIZE
    family_trials: int = FAMILY_TRIALS
    curve_epochs: int = EPOCHS
    atomic_epochs: int = ATOMIC_EPOCHS
    atomic_trials: int = ATOMIC_TRIALS
    atomic_test_trials: int = TEST_TRIALS
    general_trials: int = GENERAL_TRIALS_PER_EPOCH
    validation_polygons: int = 300
    heldout_polygons: int = 200
    heldout_trials: int = 10
    noise_sweep: bool = True
    validation_sweep: bool = True
    quick: bool = False
    command: str = field(default="", compare=False)

    @classmethod
    def paper(cls, **kwargs) -> ReproduceConfig:
        return cls(**kwargs)

    @classmethod
    def quick_run(cls, **kwargs) -> ReproduceConfig:
        small = dict(
            seeds=(0,),
            ql_epochs=30,
            predictor_epochs=4,
            test_trials=40,
            family_size=3,
            family_trials=10,
            curve_epochs=20,
            atomic_epochs=30,
            atomic_trials=60,
            atomic_test_trials=60,
            general_trials=30,
            validation_polygons=20,
            heldout_polygons=30,
            heldout_trials=4,
            noise_sweep=False,
            validation_sweep=False,
            quick=True,
        )
        return cls(**{**small, **kwargs})


def _streams(seed: int) -> dict[str, np.random.SeedSequence]:
    children = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: children[i] for name, i in STREAMS.items()}


def _rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng(_streams(seed)[name])


def _objects(cfg: ReproduceConfig, names: Sequence[str] = PAPER_OBJECTS) -> ObjectSet:
    return ObjectSet.paper(names, cfg.family_size)


def _tables_set(cfg: ReproduceConfig, seed: int) -> TrialSet:
    return trial_set(_objects(cfg), _rng(seed, "test"), cfg.test_trials, cfg.family_trials)


def _nine(cfg: ReproduceConfig, seed: int):
    return train_predictor(
        _rng(seed, "pi9"), _objects(cfg), cfg.predictor_epochs, cfg.trials_per_object
    )


def _representative(result: TrialBatch, ts: TrialSet) -> dict:
    """The trials on each object's member 0 (for Figure 12), as plain arrays."""
    keep = np.isin(ts.polygon_index, ts.objects.first)
    return {
        "object": ts.object_index[keep],
        "theta": result.theta_final[keep],
        "s_g": result.s_g[keep],
    }


# --- tasks: one experiment of one seed each; run in worker processes ---------------------------
def task_ql(cfg: ReproduceConfig, seed: int) -> dict:
    """Section 3.6.2: train Q-learning, test it greedily (Table 1 and 2, column (b))."""
    ql = train_qlearning(_rng(seed, "ql"), _objects(cfg), cfg.ql_epochs, cfg.trials_per_object)
    ts = _tables_set(cfg, seed)
    r = ts.run(QLearningComposer(q=ql.q.copy()), _rng(seed, "test_noise"))
    return {
        "q": ql.q,
        "curve": ql.failure_per_epoch,
        "temperature": ql.temperature,
        "rows": {"ql": object_rows(r, ts)},
        "fig12": {"ql": _representative(r, ts)},
    }


def task_tables(cfg: ReproduceConfig, seed: int) -> dict:
    """Section 4.3-4.4: train the nine- and five-object predictors; test KB and PI (c), (d) with
    the literal noise, PI (c) with every other reading and the noise sweep, and PI (c) with a
    predictor trained on each epoch's states only (the other reading of the training set)."""
    pred = _nine(cfg, seed)
    last = train_predictor(
        _rng(seed, "pi9"), _objects(cfg), cfg.predictor_epochs, cfg.trials_per_object,
        cumulative=False,
    )  # fmt: skip
    five = _objects(cfg, FIVE_OBJECTS)
    pred5 = train_predictor(_rng(seed, "pi5"), five, cfg.predictor_epochs, cfg.trials_per_object)
    ts = _tables_set(cfg, seed)
    comps: dict[str, Composer] = {
        "kb": KnowledgeBased(),
        "pi": PreImaging(pred.predictor),
        "pi5": PreImaging(pred5.predictor),
        "pi_last_epoch": PreImaging(last.predictor),
    }
    for reading in NOISE_READINGS:
        if reading != "literal":
            comps[f"pi_{reading}"] = PreImaging(pred.predictor, reading=reading)
    for scale in NOISE_SCALES if cfg.noise_sweep else ():
        comps[f"pi_x{scale:g}"] = PreImaging(pred.predictor, noise_scale=scale)
    rows, fig12 = {}, {}
    for key, comp in comps.items():
        r = ts.run(comp, _rng(seed, "test_noise"))
        rows[key] = object_rows(r, ts)
        if key in ("kb", "pi"):
            fig12[key] = _representative(r, ts)
    return {
        "predictor": pred.predictor,
        "predictor5": pred5.predictor,
        "predictor_curve": pred.failure_per_epoch,
        "rows": rows,
        "fig12": fig12,
    }


def general_training_set(cfg: ReproduceConfig) -> ObjectSet:
    """The general predictor's training polygons: one family of ``predictor_epochs *
    general_trials`` random convex polygons from the "train" seeds (each trial a new polygon)."""
    n = cfg.predictor_epochs * cfg.general_trials
    return ObjectSet(("random",), (tuple(polygon_set("train", n)),))


def task_general(cfg: ReproduceConfig, seed: int) -> dict:
    """Beyond the paper: train the general predictor on random polygons; test KB, nine-object PI
    and general PI (and the predictor-gradient action) on validation and held-out polygons."""
    nine = _nine(cfg, seed).predictor
    train = general_training_set(cfg)
    gen = train_predictor(
        _rng(seed, "general"), train, cfg.predictor_epochs, cfg.general_trials
    ).predictor
    out: dict = {"predictor": gen, "validation": {}, "heldout": {}}
    for kind, count, trials in (
        ("validation", cfg.validation_polygons, cfg.heldout_trials),
        ("heldout", cfg.heldout_polygons, cfg.heldout_trials),
    ):
        polys = polygon_set(kind, count)
        objects = ObjectSet((kind,), (tuple(polys),))
        ts = trial_set(objects, _rng(seed, kind), trials_per_member=trials)
        comps: dict[str, Composer] = {"kb": KnowledgeBased()}
        if kind == "heldout":
            comps["nine_literal"] = PreImaging(nine)
            comps["nine_turn"] = PreImaging(nine, reading="turn")
            comps["general_literal"] = PreImaging(gen)
            comps["general_predictor_action"] = PreImaging(gen, action="predictor")
        sweep = kind == "validation" and cfg.validation_sweep
        for reading in ("literal", "turn", "perimeter") if sweep else ("turn",):
            for th in (0.0, -0.25, -0.5, -0.75) if sweep else (0.0,):
                comps[f"general_{reading}_{th:g}"] = PreImaging(gen, reading=reading, threshold=th)
        comps["general"] = PreImaging(gen, **GENERAL_SETTINGS)
        for key, comp in comps.items():
            r = ts.run(comp, _rng(seed, f"{kind}_noise"))
            feas = r.s_g[r.feasible]
            fail = ~r.success
            out[kind][key] = {
                "failure": 100.0 * float(fail.mean()),
                "mean_s_g": float(feas.mean()) if feas.size else float("nan"),
                "failed_converged": int((fail & r.converged).sum()),
                "failed_unconverged": int((fail & ~r.converged).sum()),
                "mean_steps": float(r.steps.mean()),
            }
    return out


def task_atomic(cfg: ReproduceConfig, seed: int) -> dict:
    """Section 2: atomic actions on the irregular triangle, tested as trained and rotated."""
    tri = paper_object("irregular_triangle")
    atomic = train_atomic(
        tri, _rng(seed, "atomic"), cfg.atomic_epochs, cfg.atomic_trials, ScoreTable(tri)
    )
    tests = [
        evaluate_atomic(
            atomic.q, tri, _rng(seed, "atomic_test"), rot, cfg.atomic_test_trials, label
        )
        for label, rot in (("trained", 0.0), ("rotated", TEST_ROTATION_DEG))
    ]
    return {"q": atomic.q, "curve": atomic.failure_per_epoch, "tests": tests}


def failure_curve(
    polys: Sequence,
    batch: PolygonBatch,
    composer: Composer,
    rng: np.random.Generator,
    epochs: int,
    trials_per_object: int,
    objects: ObjectSet,
) -> np.ndarray:
    """Failure rate per epoch of a controller that does not learn (Figure 9 (a) after the predictor
    is trained, (b)); epochs run CURVE_CHUNK at a time, each chunk one batch."""
    from controllers.grasp.qlearning import epoch_objects, epoch_trials

    obj = epoch_objects(len(objects.names), trials_per_object, rng)
    out = []
    for start in range(0, epochs, CURVE_CHUNK):
        k = min(CURVE_CHUNK, epochs - start)
        idx = np.concatenate([epoch_trials(objects, obj, start + e, trials_per_object)
                              for e in range(k)])  # fmt: skip
        r = run_trials(polys, idx, composer, rng, batch=batch)
        out.append(1.0 - r.success.reshape(k, obj.size).mean(axis=1))
    return np.concatenate(out)


def task_curves(cfg: ReproduceConfig, seed: int) -> dict:
    """Figures 9, 10 and 11 (first seed only): KB and PI failure curves, and KB and PI paths on
    the square from the same initial contacts."""
    objects = _objects(cfg)
    polys = objects.polygons
    batch = PolygonBatch.of(polys)
    pred = _nine(cfg, seed)
    e_pi = max(cfg.curve_epochs - cfg.predictor_epochs, 1)
    tpo = cfg.trials_per_object
    kb = failure_curve(
        polys, batch, KnowledgeBased(), _rng(seed, "kb_curve"), cfg.curve_epochs, tpo, objects
    )
    pi = failure_curve(
        polys, batch, PreImaging(pred.predictor), _rng(seed, "pi_curve"), e_pi, tpo, objects
    )
    square = [paper_object("square")]
    theta0 = _rng(seed, "fig10").uniform(0, 2 * np.pi, (FIGURE10_TRIALS, N_CONTACTS))
    idx = np.zeros(FIGURE10_TRIALS, dtype=np.int64)
    runs = {
        key: run_trials(
            square, idx, comp, _rng(seed, "fig10_noise"), theta_initial=theta0, record_states=True
        )
        for key, comp in (("kb", KnowledgeBased()), ("pi", PreImaging(pred.predictor)))
    }
    return {
        "kb": kb,
        "pi": np.concatenate([pred.failure_per_epoch, pi]),
        "square": runs,
        "square_theta0": theta0,
    }


TASKS: dict[str, Callable[[ReproduceConfig, int], dict]] = {
    "qlearning": task_ql,
    "tables": task_tables,
    "general": task_general,
    "curves": task_curves,
    "atomic": task_atomic,
}
