"""A reproduce run small enough for the tests (seconds, not minutes), shared by the tests of
``experiments.paper reproduce`` and of its Ctrl-C behaviour."""

from __future__ import annotations

from dataclasses import replace

from experiments.paper.tasks import ReproduceConfig


def tiny_config(seeds: tuple[int, ...]) -> ReproduceConfig:
    """The quick run cut to a handful of epochs and trials, over ``seeds``, in this process."""
    return replace(
        ReproduceConfig.quick_run(),
        seeds=seeds,
        workers=1,
        ql_epochs=4,
        predictor_epochs=2,
        test_trials=8,
        family_size=2,
        family_trials=4,
        curve_epochs=4,
        atomic_epochs=4,
        atomic_trials=20,
        atomic_test_trials=20,
        general_trials=10,
        validation_polygons=4,
        heldout_polygons=4,
        heldout_trials=2,
    )
