"""The page's HTTP server (the standard library's ``ThreadingHTTPServer``): the page, its event
stream (Server-Sent Events), the overhead image, the clicks and the stop, and the files of the
run's cycles. Nothing else: an unknown route is 404, a malformed request 400, and no path is
ever taken from a request (a file is served only when the run registered its route).

Bound to the loopback address (the default), requests must name it in their ``Host`` header (a
page elsewhere cannot reach the server through a name it resolves to 127.0.0.1), and a click or
stop sent from another page (an ``Origin`` that is not the server's) is refused. The HTTP threads
never touch MuJoCo: they read the :class:`~fsm.interactive.hub.Hub` and post to the
:class:`~fsm.interactive.hub.Mailbox`."""

from __future__ import annotations

import ipaddress
import json
import socket
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

from fsm.interactive.hub import Hub, Mailbox
from fsm.user_protocol import Pixel

#: Largest request body (bytes) taken: a click is ``{"u": 1919, "v": 1439}``.
MAX_BODY = 256
#: Seconds a click waits for the task cycle's answer (the place point's set-down check).
CLICK_TIMEOUT = 60.0
#: Seconds between keep-alive comments on an idle event stream (a closed page is noticed at the
#: next one).
KEEPALIVE = 2.0
#: Seconds without a page connected (after one was) before the run counts the page as closed
#: (a reload reconnects well within it).
PAGE_GRACE = 5.0
#: What each answer of the mailbox is as an HTTP status.
CLICK_STATUS = {"taken": 200, "refused": 422, "busy": 409, "ended": 409, "timeout": 503}
#: Headers of every response: no caching, no framing (a click on a framed page is another
#: page's), no content sniffing.
COMMON_HEADERS = {
    "Cache-Control": "no-store",
    "X-Frame-Options": "DENY",
    "X-Content-Type-Options": "nosniff",
}
CSP = (
    "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
    "script-src 'self' 'unsafe-inline'; frame-ancestors 'none'"
)


def page_html() -> bytes:
    """The page (``page.html`` beside this module, a package data file)."""
    return resources.files("fsm.interactive").joinpath("page.html").read_bytes()


def parse_click(body: bytes, width: int, height: int) -> Pixel | str:
    """The pixel of a click's JSON body ``{"u": U, "v": V}`` (integers inside the ``width`` x
    ``height`` image), or what is wrong with it."""
    try:
        data = json.loads(body.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return 'the body must be JSON: {"u": U, "v": V}'
    if not isinstance(data, dict) or set(data) != {"u", "v"}:
        return 'the body must be {"u": U, "v": V}, pixel column and row, and nothing else'
    u, v = data["u"], data["v"]
    if not all(isinstance(c, int) and not isinstance(c, bool) for c in (u, v)):
        return f"u and v must be integers (pixel column and row), got {u!r}, {v!r}"
    if not (0 <= u < width and 0 <= v < height):
        return (
            f"pixel ({u}, {v}) is outside the {width}x{height} overhead image (u in "
            f"0..{width - 1}, v in 0..{height - 1}): click on the image"
        )
    return u, v


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) is this machine's loopback."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class PageServer(ThreadingHTTPServer):
    """The interactive page's server at ``address``; see the module docstring."""

    daemon_threads = True
    allow_reuse_address = False

    def __init__(self, address: tuple[str, int], hub: Hub, mailbox: Mailbox) -> None:
        if ":" in address[0]:
            self.address_family = socket.AF_INET6
        super().__init__(address, Handler)
        self.hub = hub
        self.mailbox = mailbox
        self.page = page_html()
        self.loopback = is_loopback(address[0])

    @property
    def port(self) -> int:
        return int(self.server_address[1])

    def start(self) -> threading.Thread:
        """Serve in a daemon thread, and watch for the page being closed: once a page has
        connected, no page connected for :data:`PAGE_GRACE` seconds ends the run."""
        thread = threading.Thread(
            target=self.serve_forever,
            kwargs={"poll_interval": 0.1},
            name="page-server",
            daemon=True,
        )
        thread.start()
        threading.Thread(target=self._watch_page, name="page-watch", daemon=True).start()
        return thread

    def _watch_page(self) -> None:
        hub = self.hub
        while not hub.closed and self.mailbox.stop_reason is None:
            time.sleep(0.25)
            idle = time.monotonic() - hub.last_disconnect
            if hub.ever_connected and hub.connected == 0 and idle > PAGE_GRACE:
                self.mailbox.stop("the page was closed")

    def stop(self) -> None:
        """Stop serving (the event streams end) and close the socket."""
        self.hub.close()
        self.shutdown()
        self.server_close()


class Handler(BaseHTTPRequestHandler):
    """One request to the :class:`PageServer`."""

    server: PageServer
    server_version = "graspsim"
    sys_version = ""

    def log_message(self, format: str, *args: Any) -> None:
        """Requests are not logged (the terminal shows the task cycle)."""

    # --- answers --------------------------------------------------------------------------
    def _send(self, code: int, body: bytes, content_type: str, **headers: str) -> None:
        self.send_response(code)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for key, value in {**COMMON_HEADERS, **headers}.items():
            self.send_header(key.replace("_", "-"), value)
        self.end_headers()
        self.wfile.write(body)

    def _json(self, code: int, data: dict[str, Any]) -> None:
        self._send(code, json.dumps(data).encode(), "application/json; charset=utf-8")

    def _error(self, code: int, message: str) -> None:
        self._json(code, {"error": message})

    # --- checks ---------------------------------------------------------------------------
    def _split(self) -> tuple[str, str]:
        parts = urlsplit(self.path)
        return parts.path, parts.query

    def _host_ok(self) -> bool:
        """A loopback server answers only requests addressed to a loopback name."""
        if not self.server.loopback:
            return True
        host = self.headers.get("Host", "")
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        return is_loopback(name)

    def _origin_ok(self) -> bool:
        """A click or stop comes from this server's own page (or from a script: no Origin)."""
        origin = self.headers.get("Origin")
        if origin is None:
            return True
        return urlsplit(origin).netloc == self.headers.get("Host", "")

    # --- GET ------------------------------------------------------------------------------
    def do_GET(self) -> None:
        if not self._host_ok():
            return self._error(403, "this server answers only to its loopback address")
        path, query = self._split()
        if path == "/overhead.jpg" and (not query or _version_query(query)):
            return self._image()
        if query:
            return self._error(404, f"no such page: {path}?{query}")
        if path == "/":
            return self._send(
                200, self.server.page, "text/html; charset=utf-8", Content_Security_Policy=CSP
            )
        if path == "/events":
            return self._events()
        if path == "/state.json":
            return self._json(200, self.server.hub.snapshot())
        file = self.server.hub.file(path)
        if file is not None:
            return self._file(file)
        return self._error(404, f"no such page: {path}")

    def _image(self) -> None:
        image = self.server.hub.image()
        if image is None:
            return self._error(404, "no overhead image yet: the camera has not looked")
        return self._send(200, image[0], "image/jpeg", X_Image_Version=str(image[1]))

    def _file(self, path: Any) -> None:
        try:
            body = path.read_bytes()
        except OSError as e:
            return self._error(404, f"{path.name} cannot be read: {e.strerror}")
        if path.suffix == ".json":
            return self._send(200, body, "application/json; charset=utf-8")
        return self._send(
            200,
            body,
            "application/octet-stream",
            Content_Disposition=f'attachment; filename="{path.parent.name}-{path.name}"',
        )

    def _events(self) -> None:
        self.send_response(200)
        self.send_header("Content-Type", "text/event-stream; charset=utf-8")
        for key, value in COMMON_HEADERS.items():
            self.send_header(key, value)
        self.end_headers()
        hub = self.server.hub
        try:
            with hub.subscribe() as sub:
                while True:
                    event = sub.next(KEEPALIVE)
                    if event is None:
                        if hub.closed:
                            return
                        self.wfile.write(b": keep-alive\n\n")
                    else:
                        kind, data = event
                        self.wfile.write(f"event: {kind}\ndata: {json.dumps(data)}\n\n".encode())
                    self.wfile.flush()
        except (BrokenPipeError, ConnectionResetError):
            return

    # --- POST -----------------------------------------------------------------------------
    def do_POST(self) -> None:
        if not self._host_ok():
            return self._error(403, "this server answers only to its loopback address")
        path, query = self._split()
        if query or path not in ("/click", "/stop"):
            return self._error(404, f"no such page: {self.path}")
        if not self._origin_ok():
            return self._error(403, "clicks are taken from this server's own page only")
        body = self._body()
        if body is None:
            return None
        mailbox = self.server.mailbox
        if path == "/stop":
            mailbox.stop("stopped from the page")
            return self._json(200, {"message": "the run stops; every cycle's files are kept"})
        if self.headers.get("Content-Type", "").split(";")[0].strip() != "application/json":
            return self._error(415, "a click is a JSON body: Content-Type: application/json")
        pixel = parse_click(body, mailbox.width, mailbox.height)
        if isinstance(pixel, str):
            return self._error(400, pixel)
        outcome, answer = mailbox.offer(pixel, CLICK_TIMEOUT)
        data = {"accepted": answer.accepted, "message": answer.message, "pixel": list(pixel)}
        return self._json(CLICK_STATUS[outcome], data)

    def _body(self) -> bytes | None:
        """The request's body (at most :data:`MAX_BODY` bytes), or None after answering an
        error."""
        length = self.headers.get("Content-Length")
        if length is None or not length.isdigit():
            self._error(411, "a Content-Length is required")
            return None
        if int(length) > MAX_BODY:
            self._error(413, f"the body may have at most {MAX_BODY} bytes")
            return None
        return self.rfile.read(int(length))


def _version_query(query: str) -> bool:
    """Whether ``query`` is ``v=N`` (the image's version, which the page adds to its URL)."""
    key, _, value = query.partition("=")
    return key == "v" and value.isdigit() and len(value) < 12
