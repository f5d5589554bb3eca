"""The command-line toolkit every command uses: argument types that refuse bad numbers and paths
with the range in the message, negative numbers as option values, one-line errors, exit status 2
for bad input and 130 for Ctrl-C, and atomic writes that leave no half-written file."""

from __future__ import annotations

import argparse
import os
import signal
from pathlib import Path

import pytest

from controllers.grasp.errors import PolygonError
from graspsim_base import cli
from graspsim_base.files import atomic_path, temporary_name, write_text

# (type, text, accepted value or None when refused, fragment of the refusal)
TYPE_CASES = [
    (cli.integer(1, 10), "3", 3, ""),
    (cli.integer(1, 10), "0", None, "from 1 to 10"),
    (cli.integer(1, 10), "1e9", None, "from 1 to 10"),
    (cli.integer(1, 10), "2.5", None, "integer"),
    (cli.integer(1, 10), "", None, "got ''"),
    (cli.seed, "-1", None, "from 0 to 4,294,967,295"),
    (cli.seed, "4294967296", None, "from 0"),
    (cli.number(0.0, 10.0, lo_open=True), "0", None, "(0, 10]"),
    (cli.number(0.0, 10.0, lo_open=True), "nan", None, "(0, 10]"),
    (cli.number(0.0, 10.0, lo_open=True), "inf", None, "(0, 10]"),
    (cli.number(0.0, 10.0, lo_open=True), "-1", None, "(0, 10]"),
    (cli.number(0.0, 10.0, lo_open=True), "1e-3", 1e-3, ""),
    (cli.number(), "1e400", None, "finite"),
    (cli.numbers(2, "U,V"), "-1,-2.5", (-1.0, -2.5), ""),
    (cli.numbers(2, "U,V"), "nan,nan", None, "2 finite numbers"),
    (cli.numbers(2, "U,V"), "inf,0", None, "2 finite numbers"),
    (cli.numbers(2, "U,V"), "1,2,3", None, "'U,V'"),
    (cli.numbers(3, "FX,FY,MZ", -5, 5), "1,2", None, "3 finite numbers in [-5, 5]"),
    (cli.numbers(3, "FX,FY,MZ", -5, 5), "0,0,6", None, "[-5, 5]"),
    (cli.out_dir, "", None, "empty"),
    (cli.out_dir, "  ", None, "empty"),
    (cli.out_dir, "/", None, "root folder"),
    (cli.out_dir, "//", None, "root folder"),
    (cli.out_dir, "runs/x", Path("runs/x"), ""),
    (cli.out_file(".json"), "", None, "empty"),
    (cli.out_file(".json"), "out/", None, "is a folder"),
    (cli.out_file(".json"), "out/r.txt", None, "must end in .json"),
    (cli.out_file(".png", ".jpg"), "pick", None, "must end in .png or .jpg"),
    (cli.out_file(".png", ".jpg"), "a/pick.PNG", Path("a/pick.PNG"), ""),
]


@pytest.mark.parametrize(("kind", "text", "value", "fragment"), TYPE_CASES)
def test_argument_types_accept_or_name_the_range(kind, text, value, fragment) -> None:
    if value is None:
        with pytest.raises(argparse.ArgumentTypeError) as e:
            kind(text)
        assert fragment in str(e.value)
        assert repr(text) in str(e.value) or "empty" in str(e.value)  # the value is shown
    else:
        assert kind(text) == value


def test_out_dir_refuses_an_existing_file(tmp_path: Path) -> None:
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(argparse.ArgumentTypeError, match="is a file"):
        cli.out_dir(str(f))
    with pytest.raises(argparse.ArgumentTypeError, match="is a folder"):
        cli.out_file(".json")(str(tmp_path))


def _parser() -> cli.ArgumentParser:
    p = cli.ArgumentParser(prog="prog")
    p.add_argument("--points")
    p.add_argument("--pixel", type=cli.numbers(2, "U,V"))
    p.add_argument("--gain", type=cli.number(0.0, 1.0, lo_open=True), default=0.25, help="g")
    return p


def test_negative_numbers_are_option_values() -> None:
    a = _parser().parse_args(["--points", "-0.01,0.02;0.03,-0.04", "--pixel", "-1,-1"])
    assert a.points == "-0.01,0.02;0.03,-0.04" and a.pixel == (-1.0, -1.0)
    assert _parser().parse_args(["--pixel", "-.5,3"]).pixel == (-0.5, 3.0)


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--gain", "0"], "argument --gain: must be a number in (0, 1], got '0'"),
        (["--nope", "1"], "unrecognized arguments: --nope 1"),
        (["--points"], "argument --points: expected one argument"),
        (["--pixel", "-1"], "argument --pixel: must be 2 finite numbers"),
    ],
)
def test_usage_errors_are_one_line_and_exit_2(argv, fragment, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        _parser().parse_args(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("prog: ") and fragment in err


def test_help_shows_defaults(capsys) -> None:
    with pytest.raises(SystemExit):
        _parser().parse_args(["--help"])
    assert "(default: 0.25)" in capsys.readouterr().out


def test_first_paragraph_does_not_stop_mid_sentence() -> None:
    doc = "One sentence that goes on\nover two lines.\n\nDetails."
    assert cli.first_paragraph(doc) == "One sentence that goes on over two lines."


def _raise(exc: BaseException):
    def body() -> int:
        raise exc

    return body


@pytest.mark.parametrize(
    ("body", "status", "message"),
    [
        (lambda: 0, 0, None),
        (lambda: None, 0, None),
        (lambda: 1, 1, None),
        (_raise(PolygonError("bad\npolygon")), 2, "prog: bad; polygon"),
        (_raise(cli.CommandLineError("--out", "cannot write")), 2, "prog: --out: cannot write"),
        (_raise(KeyboardInterrupt()), 130, "prog: interrupted; nothing was written"),
        (_raise(cli.Interrupted(Path("runs/x"))), 130, "interrupted; partial results in runs/x"),
        (_raise(SystemExit(2)), 2, None),
    ],
)
def test_run_main_maps_outcomes_to_exit_status(body, status, message, capsys) -> None:
    assert cli.run_main(body, prog="prog", errors=(PolygonError,)) == status
    err = capsys.readouterr().err
    if message is None:
        assert err == ""
    else:
        assert err.count("\n") == 1 and message in err


def test_unexpected_errors_are_not_hidden() -> None:
    with pytest.raises(ZeroDivisionError):
        cli.run_main(lambda: 1 // 0, prog="prog")


def test_partial_results_in_names_the_folder(tmp_path: Path, capsys) -> None:
    def body() -> int:
        with cli.partial_results_in(tmp_path):
            raise KeyboardInterrupt

    assert cli.run_main(body, prog="p") == 130
    assert capsys.readouterr().err == f"p: interrupted; partial results in {tmp_path}\n"


@pytest.mark.skipif(
    signal.getsignal(signal.SIGINT) is not signal.default_int_handler,
    reason="SIGINT is not Python's default handler in this test process",
)
def test_a_second_ctrl_c_does_not_stop_the_cleanup(tmp_path: Path, capsys) -> None:
    cleaned = []

    def body() -> int:
        try:
            os.kill(os.getpid(), signal.SIGINT)
            raise AssertionError("SIGINT did not interrupt")
        finally:
            os.kill(os.getpid(), signal.SIGINT)  # ignored while cleaning up
            cleaned.append(True)

    assert cli.run_main(body, prog="p") == 130
    assert cleaned == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_prepare_dir_checks_writability_before_work(tmp_path: Path) -> None:
    assert cli.prepare_dir(tmp_path / "a" / "b", "--out").is_dir()
    assert list((tmp_path / "a" / "b").iterdir()) == []  # the probe file is gone
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(cli.CommandLineError, match="--out: cannot write into"):
        cli.prepare_dir(blocker / "sub", "--out")
    with pytest.raises(cli.CommandLineError, match="--json: cannot write into"):
        cli.prepare_file(blocker / "r.json", "--json")


def test_atomic_write_keeps_the_old_file_when_interrupted(tmp_path: Path) -> None:
    target = tmp_path / "r.json"
    write_text(target, "old")
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as tmp:
        assert tmp.suffix == ".json" and tmp.parent == tmp_path
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]
    write_text(target, "new")
    assert target.read_text() == "new" and not temporary_name(target).exists()
