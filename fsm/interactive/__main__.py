"""``python -m fsm.interactive``: pick and place by clicking on the overhead image in a web page,
as the paper's user did (section 5); each cycle's summary and recording are written as
``fsm.run`` writes an episode's.

It builds the world, serves the page on ``--host``:``--port`` (loopback by default) and prints
its address; the run ends with the page's stop button, by closing the page, or by Ctrl-C, every
cycle's files written. Exit status: 0 the run ended (whatever the cycles' outcomes: each is in
its summary), 1 the world could not go on (an unstable simulation or an internal error), 2 bad
input, 130 Ctrl-C."""

from __future__ import annotations

import argparse
import sys
import time
import uuid
from collections.abc import Sequence
from functools import partial
from pathlib import Path

from fsm.context import EpisodeOptions
from fsm.interactive.hub import Hub, Mailbox
from fsm.interactive.server import PageServer, is_loopback
from fsm.layout import episode_scene
from fsm.live import DEFAULT_LIVE_PORT, LiveStream, check_host, listen_port, serve_stream
from fsm.run import (
    add_controller_and_approach,
    add_hand,
    add_lateral_gate,
    add_models,
    add_scene,
    task_settings,
)
from hand_sim.clitools import (
    ERRORS,
    ArgumentParser,
    CommandLineError,
    add_perturb_argument,
    first_paragraph,
    integer,
    out_dir,
    partial_results_in,
    prepare_dir,
    run_main,
)
from vision import DEFAULT_HEIGHT as IMAGE_HEIGHT
from vision import DEFAULT_WIDTH as IMAGE_WIDTH

PROG = "python -m fsm.interactive"
#: The page's address by default: this machine only.
DEFAULT_HOST, DEFAULT_PORT = "127.0.0.1", 8765
#: Seconds the page's event streams get to send the run's end before the server stops.
DRAIN_TIME = 0.5


def parser() -> ArgumentParser:
    ap = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
    add_scene(ap)
    add_controller_and_approach(ap)
    add_models(ap)
    add_hand(ap)
    add_lateral_gate(ap)
    add_perturb_argument(ap)
    ap.add_argument(
        "--out",
        type=out_dir,
        default=None,
        help="the run's folder, one cycle-NNN/ folder per cycle in it; must hold no cycles "
        "yet (default runs/interactive-<scene>-<seed>-<date>-<time>)",
    )
    ap.add_argument(
        "--host",
        default=DEFAULT_HOST,
        help="address the page (and the rerun stream) is served on; anything but the loopback "
        "address lets other machines drive the robot",
    )
    ap.add_argument(
        "--port", type=integer(0, 65535), default=DEFAULT_PORT, help="the page's port (0: any free)"
    )
    ap.add_argument(
        "--rerun-port",
        type=integer(0, 65535),
        default=DEFAULT_LIVE_PORT,
        help="port of the live recording for the rerun viewer (0: any free)",
    )
    return ap


def options_from_args(args: argparse.Namespace) -> EpisodeOptions:
    """The episode options of the run (every cycle's), checked: the output folder (created, and
    holding no cycles of an earlier run)."""
    stem = Path(args.scene).stem if args.scene.endswith(".toml") else args.scene
    default = Path("runs") / f"interactive-{stem}-{args.seed}-{time.strftime('%Y%m%d-%H%M%S')}"
    out = args.out or default
    if out.is_dir() and any(out.glob("cycle-*")):
        raise CommandLineError(
            "--out", f"{out} holds the cycles of an earlier run; choose an empty folder"
        )
    return EpisodeOptions(
        scene=args.scene,
        seed=args.seed,
        blocks=args.blocks,
        out=prepare_dir(out, "--out"),
        **task_settings(args),
    )


def _page_server(host: str, port: int, hub: Hub, mailbox: Mailbox) -> PageServer:
    try:
        return PageServer((host, port), hub, mailbox)
    except OSError as e:
        raise CommandLineError(
            "--port", f"cannot serve on {host}:{port} ({e.strerror or e}); choose another port"
        ) from None


def _url(host: str, port: int) -> str:
    shown = "127.0.0.1" if host in ("", "0.0.0.0") else host
    return f"http://[{shown}]:{port}/" if ":" in shown else f"http://{shown}:{port}/"


def run(argv: Sequence[str] | None) -> int:
    args = parser().parse_args(argv)
    episode_scene(args.scene, args.seed, args.blocks)  # an unknown scene is bad input
    check_host(args.host, "--host")
    listen_port(args.host, args.port, "--port")  # the ports are free
    stream = serve_stream(args.host, args.rerun_port, "--rerun-port")
    options = options_from_args(args)  # creates the output folder: the last check
    hub, mailbox = Hub(), Mailbox(IMAGE_WIDTH, IMAGE_HEIGHT)
    server = _page_server(args.host, args.port, hub, mailbox)
    from fsm.interactive.driver import Driver
    from fsm.recording import EpisodeRecorder

    keepalive = _serve_rerun(stream)
    hub.publish("rerun", {"command": stream.viewer_command, "url": stream.url})
    server.start()
    if not is_loopback(args.host):
        print(
            f"{PROG}: serving on {args.host}: anyone who can reach it can drive the robot",
            file=sys.stderr,
        )
    print(f"the page: {_url(args.host, server.port)} (Ctrl-C ends the run)", flush=True)
    print(f"the live 3-D view: {stream.viewer_command}", flush=True)

    def recorder(path: Path, world: object) -> EpisodeRecorder:
        import rerun as rr

        return EpisodeRecorder(path, world, live=rr.GrpcSink(stream.url))

    driver = Driver(options, hub, mailbox, recorder, announce=partial(print, flush=True))
    try:
        with partial_results_in(options.out):
            status = driver.run()
    finally:
        hub.drain(DRAIN_TIME)
        server.stop()
        keepalive.disconnect()
    print(f"{driver.ended}; {len(driver.results)} cycle(s) written in {options.out}")
    return status


def _serve_rerun(stream: LiveStream) -> object:
    """Start serving ``stream`` (the rerun viewer connects to it; every cycle's recording is
    sent to it): a recording of its own holds the server for the run."""
    import rerun as rr

    keepalive = rr.RecordingStream("graspsim", recording_id=str(uuid.uuid4()))
    keepalive.set_sinks(stream.sink())
    return keepalive


def main(argv: Sequence[str] | None = None) -> int:
    """Serve the interactive task cycle; see the module docstring for the exit status."""
    return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    sys.exit(main())
