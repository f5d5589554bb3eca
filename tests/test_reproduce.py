"""``reproduce``: a tiny seeded run writes the report, figures and models, bit-identically, and the
trained models serve ``trials --controller ql|pi``."""

import json
from dataclasses import replace

import pytest

from controllers.grasp.cli import main
from controllers.grasp.reproduce import ReproduceConfig, reproduce

TINY = replace(
    ReproduceConfig.quick_run(),
    ql_epochs=4,
    predictor_epochs=2,
    test_trials=8,
    curve_epochs=4,
    atomic_epochs=4,
    atomic_trials=20,
    atomic_test_trials=20,
    random_polygons=4,
    random_trials=2,
)

COMPARED = (
    "report.md",
    "results.json",
    "ql_q.npy",
    "pi_predictor.json",
    "pi_predictor_five.json",
    "atomic_q.npy.gz",
    "fig09_failure_curves.png",
    "fig11_fs_map_visits.png",
)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    a, b = tmp_path_factory.mktemp("a"), tmp_path_factory.mktemp("b")
    res = reproduce(a, seed=1, config=TINY, progress=lambda _: None)
    reproduce(b, seed=1, config=TINY, progress=lambda _: None)
    return a, b, res


def test_same_seed_same_artefacts(runs):
    a, b, _ = runs
    for name in COMPARED:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert len(list(a.glob("fig*.png"))) == 9


def test_report_sets_our_numbers_beside_the_papers(runs):
    a, _, res = runs
    text = (a / "report.md").read_text()
    assert "10.06" in text and "3.6052" in text and "0.138" in text
    assert abs(res["appendix_a"]["theta_T"] - 3.6052) < 1e-3
    assert set(res["table2"]) == {"kb", "ql", "pi", "pi5"}
    assert json.loads((a / "results.json").read_text())["seed"] == 1


def test_trials_cli_uses_saved_models(runs, capsys):
    a, _, _ = runs
    for ctrl in ("ql", "pi"):
        assert main(["trials", "--controller", ctrl, "--models", str(a), "--trials", "5"]) == 0
        assert f"{ctrl}: failure" in capsys.readouterr().out


def test_trials_cli_without_models_says_how_to_train(tmp_path, capsys):
    assert main(["trials", "--controller", "pi", "--models", str(tmp_path / "x")]) == 2
    assert "reproduce --out" in capsys.readouterr().err
