"""``reproduce``: a tiny seeded run writes the report, figures and models, bit-identically, and the
trained models serve ``trials --controller ql|pi``."""

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

from controllers.grasp.cli import main
from controllers.grasp.qlearning import ACTIONS, N_BINS, save_q_table
from controllers.grasp.reproduce import ReproduceConfig, reproduce
from controllers.grasp.run_folder import check_finished_run, mark_started

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


def test_a_finished_run_is_marked_with_its_seed_and_model_hashes(runs):
    a, _, _ = runs
    run = json.loads((a / "results.json").read_text())["run"]
    assert run["finished"] is True and run["seed"] == 1
    assert set(run["models"]) == {"ql_q.npy", "pi_predictor.json", "pi_predictor_five.json",
                                  "atomic_q.npy.gz"}  # fmt: skip
    assert check_finished_run(a) == 1
    assert not list(a.glob(".*"))  # no temporary file left behind


def _copy(src, dst):
    shutil.copytree(src, dst)
    return dst


@pytest.mark.parametrize(
    ("spoil", "message"),
    [
        ("other_model", "was not written by the finished run recorded in"),
        ("unfinished", "(seed 1) did not finish"),
        ("old_results", "carries no completion mark"),
        ("no_results", "holds no reproduce run"),
        ("missing_model", "is missing from the finished run"),
    ],
)
def test_trials_refuses_models_of_an_unfinished_or_mixed_run(
    runs, tmp_path, capsys, spoil, message
):
    a, _, _ = runs
    d = _copy(a, tmp_path / "run")
    results = d / "results.json"
    if spoil == "other_model":  # a model of another run beside the finished run's results
        save_q_table(np.zeros((N_BINS * N_BINS, len(ACTIONS))), d / "ql_q.npy")
    elif spoil == "unfinished":
        mark_started(d, 1)
    elif spoil == "old_results":
        data = json.loads(results.read_text())
        del data["run"]
        results.write_text(json.dumps(data))
    elif spoil == "no_results":
        results.unlink()
    else:
        (d / "pi_predictor.json").unlink()
    for ctrl in ("ql", "pi"):
        assert main(["trials", "--controller", ctrl, "--models", str(d), "--trials", "5"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0] and "--models" in err[0], err
