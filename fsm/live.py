"""The live 3-D view of a running episode in the rerun viewer: the episode's recording streamed
to a viewer as it is logged, besides the ``.rrd`` file (``fsm.run --live`` serves the stream,
``fsm.run --connect URL`` sends it to a viewer already running; the interactive page serves one
stream for all its cycles). The viewer opens it with ``rerun --connect URL``.

The addresses are checked before any work starts: a port to serve on must be free, a viewer to
connect to must be listening. rerun's own viewer listens on 9876 by default; graspsim serves on
:data:`DEFAULT_LIVE_PORT` beside it."""

from __future__ import annotations

import socket
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

from hand_sim.clitools import CommandLineError

#: Port the live stream is served on by default (the rerun viewer's own default is 9876).
DEFAULT_LIVE_PORT = 9877
#: Seconds to wait for a running viewer to answer before refusing ``--connect``.
CONNECT_TIMEOUT = 2.0
#: URL schemes the rerun viewer takes (``rerun --help``), and the path a stream is at.
SCHEMES = ("rerun", "rerun+http", "rerun+https")
PROXY_PATH = "/proxy"


@dataclass(frozen=True)
class LiveStream:
    """Where an episode's recording is streamed: ``url`` (``rerun+http://HOST:PORT/proxy``),
    served by this process on ``host``:``port`` (``serve``) or sent to a viewer listening
    there."""

    url: str
    host: str
    port: int
    serve: bool

    @property
    def viewer_command(self) -> str:
        """The command line that opens the stream in the rerun viewer."""
        return f"rerun --connect {self.url}"

    def sink(self) -> Any:
        """A rerun sink for this stream (``rr.GrpcServerSink`` or ``rr.GrpcSink``); a
        ``GrpcServerSink`` starts serving when the recording that takes it is set up."""
        import rerun as rr

        if self.serve:
            return rr.GrpcServerSink(bind_ip=self.host, port=self.port)
        return rr.GrpcSink(self.url)


def _url_host(host: str) -> str:
    """``host`` as it goes in a URL a viewer on this machine can open."""
    if host in ("", "0.0.0.0"):
        return "127.0.0.1"
    if host == "::":
        return "[::1]"
    return f"[{host}]" if ":" in host else host


def _address(host: str, port: int, flag: str) -> tuple[int, tuple[Any, ...]]:
    try:
        family, _, _, _, sockaddr = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except (OSError, UnicodeError) as e:
        raise CommandLineError(flag, f"cannot resolve the address {host!r} ({e})") from None
    return family, sockaddr


def check_host(host: str, flag: str) -> None:
    """Refuse an address ``host`` that does not resolve (:class:`CommandLineError` naming
    ``flag``)."""
    _address(host, 0, flag)


def listen_port(host: str, port: int, flag: str) -> int:
    """``port`` (or, for 0, a free port) after checking that a server can listen on it at
    ``host``; :class:`CommandLineError` naming ``flag`` otherwise."""
    family, sockaddr = _address(host, port, flag)
    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.bind(sockaddr)
            return int(s.getsockname()[1])
    except OSError as e:
        raise CommandLineError(
            flag,
            f"cannot listen on {host}:{port} ({e.strerror or e}); choose another port, "
            "or 0 for any free one",
        ) from None


def serve_stream(host: str, port: int, flag: str) -> LiveStream:
    """A stream this process serves at ``host``:``port`` (0: any free port), checked free."""
    port = listen_port(host, port, flag)
    return LiveStream(f"rerun+http://{_url_host(host)}:{port}{PROXY_PATH}", host, port, True)


def connect_stream(text: str, flag: str) -> LiveStream:
    """The stream to a running viewer at ``text``: a URL ``rerun+http://HOST:PORT/proxy`` (or
    ``rerun://``, ``rerun+https://``) or a port on this machine, as ``rerun --connect`` takes
    it; refused unless something listens there."""
    text = text.strip()
    if text.isdigit():
        text = f"rerun+http://127.0.0.1:{text}{PROXY_PATH}"
    parts = urlsplit(text)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme not in SCHEMES or not parts.hostname or port is None:
        raise CommandLineError(
            flag,
            f"must be a viewer's URL such as rerun+http://127.0.0.1:9876{PROXY_PATH} (schemes "
            f"{', '.join(s + '://' for s in SCHEMES)}) or a port, got {text!r}",
        )
    if parts.path != PROXY_PATH or parts.query or parts.fragment:
        raise CommandLineError(flag, f"the URL's path must be {PROXY_PATH}, got {text!r}")
    family, sockaddr = _address(parts.hostname, port, flag)
    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.settimeout(CONNECT_TIMEOUT)
            s.connect(sockaddr)
    except OSError as e:
        raise CommandLineError(
            flag,
            f"no viewer listens at {text} ({e.strerror or e}); start one with `rerun` (it "
            "listens on 9876), or use --live to serve the stream instead",
        ) from None
    return LiveStream(text, parts.hostname, port, False)
