"""``reproduce``: a tiny seeded run writes the report, figures and models, bit-identically whether
its tasks run in this process or in a pool of two, and the trained models serve ``trials``."""

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

from controllers.grasp.cli import main
from controllers.grasp.objects import PAPER_LABELS
from controllers.grasp.qlearning import ACTIONS, N_BINS, save_q_table
from controllers.grasp.run_folder import check_finished_run, mark_started
from controllers.grasp.shipped import check_figures
from experiments.paper.reproduce import MODEL_FILES, reproduce
from tests.experiments.tiny_reproduce import tiny_config

TINY = tiny_config((1, 2))

# Tests of ``runs`` (two whole reproduce runs) are marked ``e2e``, as whole experiment runs.

COMPARED = (
    "report.md",
    "results.json",
    "ql_q.npy",
    "pi_predictor_nine.json",
    "pi_predictor_five.json",
    "pi_predictor_general.json",
    "atomic_q.npy.gz",
    "fig09_failure_curves.png",
    "fig11_fs_map_visits.png",
    "fig12_configurations.png",
)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    a, b = tmp_path_factory.mktemp("a"), tmp_path_factory.mktemp("b")
    res = reproduce(a, TINY, progress=lambda _: None)
    reproduce(b, replace(TINY, workers=2), progress=lambda _: None)
    return a, b, res


@pytest.mark.e2e
def test_same_seeds_same_artefacts_in_process_or_in_a_pool(runs):
    a, b, _ = runs
    for name in COMPARED:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert len(list(a.glob("fig*.png"))) == 9


@pytest.mark.e2e
def test_report_sets_our_numbers_beside_the_papers_with_seed_spread(runs):
    a, _, res = runs
    text = (a / "report.md").read_text()
    assert "Seeds 1, 2" in text  # the paper's figures beside ours are constants: not checked
    assert "±" in text and "5-95 %" in text
    for reading in ("literal", "gradient", "turn", "perimeter"):
        assert f"| {reading}:" in text or f"{reading}: " in text
    assert abs(res["appendix_a"]["theta_T"] - 3.6052) < 1e-3
    tables = res["tables"]
    assert {"kb", "ql", "pi", "pi5", "pi_gradient", "pi_turn", "pi_perimeter"} <= set(tables)
    kb = tables["kb"]["rows"]["square"]["failure"]
    per_seed = [res["per_seed"]["kb"][s]["square"]["failure"] for s in ("1", "2")]
    assert kb["mean"] == pytest.approx(sum(per_seed) / 2)
    assert "spread" in tables["kb"]["rows"]["irregular_triangle"]
    assert "spread" not in tables["kb"]["rows"]["square"]
    saved = json.loads((a / "results.json").read_text())
    assert saved["seeds"] == [1, 2]
    assert set(saved["general"]["heldout"]) >= {"kb", "nine_literal", "general"}


def _section(text: str, heading: str) -> list[str]:
    """The table rows of the report section under ``heading`` (header and rule left out)."""
    lines = text.split(heading, 1)[1].split("\n## ", 1)[0].splitlines()
    return [ln for ln in lines if ln.startswith("| ") and not ln.startswith("| Object")]


@pytest.mark.e2e
def test_report_rows_show_the_computed_results(runs):
    """The 'ours' figures of the report are computed: in Table 2, each regular object's cell is
    the mean and sample SD over the per-seed results, each of them a whole number of the 8 test
    trials; Appendix A shows the theta(T) the solver found."""
    a, _, res = runs
    text = (a / "report.md").read_text()
    rows = {ln.split("|")[1].strip(): ln for ln in _section(text, "## Table 2")}
    for name in ("triangle", "square", "pentagon", "hexagon"):
        cells = [c.strip() for c in rows[PAPER_LABELS[name]].strip().strip("|").split("|")[1:]]
        for key, shown in zip(("kb", "ql", "pi", "pi5"), cells, strict=True):
            seeds = [res["per_seed"][key][s][name]["failure"] for s in ("1", "2")]
            for f in seeds:
                assert f * TINY.test_trials / 100.0 == pytest.approx(
                    round(f * TINY.test_trials / 100.0)
                )
            expected = f"{np.mean(seeds):.2f} ± {np.std(seeds, ddof=1):.2f}"
            assert shown.split(" / ")[0] == expected, (name, key)
    assert f"theta(T) = {res['appendix_a']['theta_T']:.5f} rad" in text


@pytest.mark.e2e
def test_provenance_records_the_run_and_its_checks(runs):
    a, _, _ = runs
    prov = json.loads((a / "provenance.json").read_text())
    assert prov["seed"] == 1 and prov["command"].startswith("python -m experiments.paper reproduce")
    assert len(prov["git_commit"]) >= 7 and prov["date"][:2] == "20"
    assert set(prov["models"]) >= {"ql_q.npy", "pi_predictor_general.json"}
    assert prov["checks"] == check_figures(a)


@pytest.mark.e2e
def test_trials_cli_uses_saved_models(runs, capsys):
    a, _, _ = runs
    for ctrl in ("ql", "pi", "pi9", "pi5"):
        assert main(["trials", "--controller", ctrl, "--models", str(a), "--trials", "5"]) == 0
        assert f"{ctrl}: failure" in capsys.readouterr().out


def test_trials_cli_without_models_says_how_to_train(tmp_path, capsys):
    assert main(["trials", "--controller", "pi", "--models", str(tmp_path / "x")]) == 2
    assert "python -m experiments.paper reproduce --out" in capsys.readouterr().err


@pytest.mark.e2e
def test_a_finished_run_is_marked_with_its_first_seed_and_model_hashes(runs):
    a, _, _ = runs
    run = json.loads((a / "results.json").read_text())["run"]
    assert run["finished"] is True and run["seed"] == 1
    assert set(run["models"]) == set(MODEL_FILES)
    assert check_finished_run(a) == 1
    assert not list(a.glob(".*"))  # no temporary file left behind


def _copy(src, dst):
    shutil.copytree(src, dst)
    return dst


@pytest.mark.e2e
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
        (d / "pi_predictor_general.json").unlink()
    for ctrl in ("ql", "pi"):
        assert main(["trials", "--controller", ctrl, "--models", str(d), "--trials", "5"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0] and "--models" in err[0], err
