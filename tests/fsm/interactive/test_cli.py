"""``python -m fsm.interactive``'s command contract: bad input is one line on stderr naming the
flag, exit status 2, before any work (no world, no server, nothing written)."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from fsm.interactive.__main__ import main


@pytest.fixture
def taken_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scene", "nowhere"], "unknown scene"),
        (["--seed", "-1"], "--seed"),
        (["--port", "70000"], "--port"),
        (["--rerun-port", "-5"], "--rerun-port"),
        (["--host", "no-such-host.invalid"], "--host: cannot resolve"),
        (["--controller", "xx"], "--controller"),
        (["--pick-pixel", "1,1"], "unrecognized arguments: --pick-pixel"),
        (["--out", ""], "--out"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    args = argv if "--out" in argv else [*argv, "--out", str(out)]
    code = main(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and message in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("flag", ["--port", "--rerun-port"])
def test_a_port_in_use_is_refused_before_any_work(
    flag: str, taken_port: int, tmp_path: Path, capsys
) -> None:
    out = tmp_path / "o"
    other = "--rerun-port" if flag == "--port" else "--port"
    code = main([flag, str(taken_port), other, "0", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith(f"python -m fsm.interactive: {flag}: cannot listen on 127.0.0.1:")
    assert not out.exists()


def test_a_folder_holding_an_earlier_runs_cycles_is_refused(tmp_path: Path, capsys) -> None:
    (tmp_path / "cycle-001").mkdir()
    code = main(["--out", str(tmp_path), "--port", "0", "--rerun-port", "0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "holds the cycles of an earlier run" in err[0]
