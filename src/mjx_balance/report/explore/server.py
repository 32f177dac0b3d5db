"""The explore page's HTTP server: the standard library's ``ThreadingHTTPServer`` on 127.0.0.1.

Why the standard library: the page needs four GET endpoints and static files; a framework
(Flask, aiohttp, ...) would add a dependency and a thread or event-loop model of its own for
less code than it saves. The rules it keeps:

- bound to 127.0.0.1 only (port 0: a free one); a request whose ``Host`` is not
  ``127.0.0.1:PORT`` or ``localhost:PORT`` is refused (a web page elsewhere cannot reach the
  server through a name that resolves here: DNS rebinding);
- GET only (anything else: 405), one endpoint per action:

      /                     the page (static/index.html)
      /static/NAME          explore.js, explore.css (nothing else)
      /api/folder           the folder: its kind, maps (boundaries), layers, units, palette
      /api/map?map=KEY      one map's cells
      /api/run?map=KEY&force=F&duration=T
                            one cell's run, computed on demand or read from the folder
      /files/PATH           a file of the folder (its figures): never a file outside it (no
                            ``..``, no hidden name, no symbolic link that leads out), never a
                            folder listing; served in a sandbox (no script of a file runs)

- every answer is JSON ``{"error": "..."}`` when it is not the thing asked for (400 for a
  value or more than ``MAX_FIELDS`` query fields, 403 for a refused path, 404 for what is not
  there, 405 for any method but GET, 414 for a request line over 64 kB: also the
  answers the standard library writes itself, :meth:`Handler.send_error`), shown in the page;
  an unexpected failure is one line in the log (at most ``LOG_CHARS`` of the path and of the
  message) and a 500 with its message, never a traceback.
"""

from __future__ import annotations

import dataclasses
import contextlib
import json
import logging
import mimetypes
import os
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any, Iterator
from urllib.parse import parse_qs, unquote, urlsplit

import numpy as np

from ...model.params import ParameterError
from .folder import Folder, MapCache, folder_json, inside, open_folder
from .runs import Runs, Stopping

log = logging.getLogger("mjx_balance")

HOST = "127.0.0.1"
MAX_FIELDS = 16  # query fields a request may carry (the endpoints take at most 3)
LOG_CHARS = 200  # of a request's path and of a message, in a log line
ANSWER_END_S = 30.0  # the longest a stopping server waits for the requests under way
STATIC = {
    "index.html": "text/html; charset=utf-8",
    "explore.js": "text/javascript; charset=utf-8",
    "explore.css": "text/css; charset=utf-8",
}
PAGE_POLICY = (
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
    "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
)
FILE_POLICY = "sandbox; default-src 'none'; img-src 'self' data:; style-src 'unsafe-inline'"


def short(text: str) -> str:
    """``text`` cut to LOG_CHARS characters (a request's path can be 64 kB)."""
    return text if len(text) <= LOG_CHARS else text[: LOG_CHARS - 1] + "…"


class HttpError(Exception):
    """A request answered with ``status`` and ``{"error": message}``."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


def check_port(port: Any) -> int:
    """A TCP port: a whole number in [0, 65535] (0: a free one)."""
    if isinstance(port, bool) or not isinstance(port, (int, np.integer)) or not 0 <= port <= 65535:
        raise ParameterError(
            f"port = {port!r}: must be a whole number in [0, 65535] (0: a free one)"
        )
    return int(port)


def folder_file(root: Path, text: str) -> Path:
    """The file ``text`` (a URL path, %-encoded, relative to the folder) names inside ``root``;
    HttpError 403 for a name that leads outside it or is hidden, 404 for none."""
    try:
        name = unquote(text, errors="strict")
    except UnicodeDecodeError:
        raise HttpError(400, f"{text!r}: not a file name (its %-escapes are not UTF-8)") from None
    parts = [p for p in name.split("/") if p]
    if "\x00" in name or "\\" in name or not parts or any(p.startswith(".") for p in parts):
        raise HttpError(
            403, f"refused: {name!r} is not a file of the folder (no '..', no hidden name)"
        )
    path = root.joinpath(*parts)
    if not inside(root, path):
        raise HttpError(403, f"refused: {name!r} leads outside the folder")
    if not path.is_file():
        raise HttpError(404, f"{name!r}: no such file in the folder")
    return path.resolve()


def one_value(query: dict[str, list[str]], name: str) -> str:
    values = query.get(name, [])
    if len(values) != 1:
        raise ParameterError(f"{name}: give one value (got {len(values)})")
    return values[0]


class Handler(BaseHTTPRequestHandler):
    """GET only; every answer through :meth:`send`."""

    server: "Server"
    server_version = "mjx-balance-explore"
    sys_version = ""

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("explore: %s", short(format % args))

    def send(self, status: int, body: bytes, ctype: str, policy: str = PAGE_POLICY) -> None:
        self.send_response(status)
        for key, value in (
            ("Content-Type", ctype),
            ("Content-Length", str(len(body))),
            ("Cache-Control", "no-store"),
            ("X-Content-Type-Options", "nosniff"),
            ("Referrer-Policy", "no-referrer"),
            ("Content-Security-Policy", policy),
            ("Cross-Origin-Resource-Policy", "same-origin"),
        ):
            self.send_header(key, value)
        if status == HTTPStatus.METHOD_NOT_ALLOWED:
            self.send_header("Allow", "GET")
        self.end_headers()
        if self.command == "HEAD":
            return  # the headers only (and a 405)
        try:
            self.wfile.write(body)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the page went away

    def send_json(self, status: int, value: Any) -> None:
        body = json.dumps(value, allow_nan=False, separators=(",", ":")).encode()
        self.send(status, body, "application/json; charset=utf-8")

    def refuse_method(self) -> None:
        self.send_json(
            HTTPStatus.METHOD_NOT_ALLOWED,
            {"error": f"{short(self.command)} is refused: this server answers GET only"},
        )

    do_POST = do_PUT = do_DELETE = do_PATCH = do_HEAD = do_OPTIONS = refuse_method

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """The answers the standard library writes itself (a method without a ``do_``
        handler: 501, a request line over 64 kB: 414, a malformed request: 400), as JSON like
        every other answer; a method this server has no handler for is 405, as any other
        method but GET."""
        self.close_connection = True
        if code == HTTPStatus.NOT_IMPLEMENTED and self.command:
            return self.refuse_method()
        try:
            phrase = HTTPStatus(code).phrase
        except ValueError:
            phrase = "error"
        self.send_json(code, {"error": short(message or phrase)})

    def do_GET(self) -> None:
        with self.server.answering():
            self.answer()

    def answer(self) -> None:
        try:
            self.check_host()
            self.route(urlsplit(self.path))
        except HttpError as exc:
            self.send_json(exc.status, {"error": str(exc)})
        except ParameterError as exc:
            self.send_json(HTTPStatus.BAD_REQUEST, {"error": str(exc)})
        except (KeyboardInterrupt, Stopping):  # a signal reached this request's work, or the
            # server began to stop before its run started
            self.send_json(HTTPStatus.SERVICE_UNAVAILABLE, {"error": "the server is stopping"})
        except Exception as exc:
            first = short((str(exc).splitlines() or [""])[0])
            log.warning(f"explore: {short(self.path)}: {type(exc).__name__}: {first}")
            self.send_json(
                HTTPStatus.INTERNAL_SERVER_ERROR,
                {"error": f"internal error ({type(exc).__name__}): {first}"},
            )

    def check_host(self) -> None:
        port = self.server.server_address[1]
        if self.headers.get("Host", "") not in (f"{HOST}:{port}", f"localhost:{port}"):
            raise HttpError(403, f"refused: the page is served as http://{HOST}:{port}/ only")

    def route(self, url: Any) -> None:
        explorer = self.server.explorer
        try:
            query = parse_qs(url.query, keep_blank_values=True, max_num_fields=MAX_FIELDS)
        except ValueError:  # more fields than MAX_FIELDS
            raise HttpError(400, f"too many query fields: at most {MAX_FIELDS}") from None
        if url.path in ("/", "/index.html"):
            return self.static("index.html")
        if url.path.startswith("/static/"):
            return self.static(url.path[len("/static/") :])
        if url.path.startswith("/files/"):
            path = folder_file(explorer.folder.root, url.path[len("/files/") :])
            ctype = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
            return self.send(HTTPStatus.OK, path.read_bytes(), ctype, FILE_POLICY)
        answer = {
            "/api/folder": explorer.folder_json,
            "/api/map": explorer.map_json,
            "/api/run": explorer.run_json,
        }.get(url.path)
        if answer is None:
            raise HttpError(404, f"{url.path!r}: no such page or endpoint")
        return self.send_json(HTTPStatus.OK, answer(query))

    def static(self, name: str) -> None:
        if name not in STATIC:
            raise HttpError(404, f"{name!r}: no such file of the page")
        body = (resources.files(__package__) / "static" / name).read_bytes()
        self.send(HTTPStatus.OK, body, STATIC[name])


class Server(ThreadingHTTPServer):
    """Counts the requests being answered, so that a stopping server waits for them
    (:meth:`wait_answered`) before the process may exit: a request's thread may be inside
    MuJoCo's, OSQP's or Arrow's C++ code, and a process that exits under it aborts ("terminate
    called without an active exception", exit 134). After a signal, a run under way ends at
    its next control period (runtime.signals.check)."""

    daemon_threads = True  # a connection that never sends its request does not hold the exit
    explorer: "Explorer"

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.busy = threading.Condition()
        self.in_flight = 0

    @contextlib.contextmanager
    def answering(self) -> Iterator[None]:
        with self.busy:
            self.in_flight += 1
        try:
            yield
        finally:
            with self.busy:
                self.in_flight -= 1
                self.busy.notify_all()

    def wait_answered(self, timeout: float = ANSWER_END_S) -> bool:
        """Wait (up to ``timeout``) until no request is being answered; whether none is."""
        with self.busy:
            return self.busy.wait_for(lambda: self.in_flight == 0, timeout)

    def handle_error(self, request: Any, client_address: Any) -> None:
        import sys

        exc = sys.exc_info()[1]
        log.debug(f"explore: connection from {client_address}: {type(exc).__name__}: {exc}")


class Explorer:
    """The explore page of one output folder, served on 127.0.0.1 (``url``).

    ``Explorer(folder, port=0)`` opens the folder and binds the port (ParameterError: not a
    folder with a map, a port in use); :meth:`start` serves in a background thread (a
    notebook), :meth:`serve_forever` in this one until Ctrl-C; :meth:`stop` ends it. No file is
    written once it stops (a run under way is not kept)."""

    def __init__(self, folder: str | os.PathLike[str], *, port: int = 0):
        self.folder: Folder = open_folder(folder)
        port = check_port(port)
        try:
            self.server = Server((HOST, port), Handler)
        except OSError as exc:
            raise ParameterError(
                f"port {port}: {exc.strerror or exc}"
                + ("; leave the port out for a free one" if port else "")
            ) from None
        self.server.explorer = self
        self.cache = MapCache()
        self.runs = Runs(self.folder)
        self.thread: threading.Thread | None = None
        self._lock = threading.Lock()

    @property
    def port(self) -> int:
        return int(self.server.server_address[1])

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}/"

    def reopen(self) -> Folder:
        """The folder as it stands now (a cohort's new subjects, a compare's new variants)."""
        try:
            folder = open_folder(self.folder.root)
        except ParameterError as exc:
            raise HttpError(404, str(exc)) from None
        with self._lock:
            self.folder = dataclasses.replace(folder, shown=self.folder.shown)
            self.runs.folder = self.folder
        return self.folder

    def folder_json(self, query: dict[str, list[str]]) -> dict[str, Any]:
        answer = folder_json(self.reopen(), self.cache)
        if query.get("stamp") == [answer["stamp"]]:
            return {"stamp": answer["stamp"], "unchanged": True}
        return answer

    def map_json(self, query: dict[str, list[str]]) -> dict[str, Any]:
        folder = self.reopen()
        return self.cache.get(folder, folder.map(one_value(query, "map")))

    def run_json(self, query: dict[str, list[str]]) -> dict[str, Any]:
        folder = self.reopen()
        found = folder.map(one_value(query, "map"))
        cells = self.cache.get(folder, found)
        grid = (np.asarray(cells["forces"], float), np.asarray(cells["durations"], float))
        return self.runs.get(found, query, grid)

    def serve_forever(self) -> None:
        """Serve in this thread until interrupted (Ctrl-C: KeyboardInterrupt), then close."""
        try:
            self.server.serve_forever(poll_interval=0.2)
        finally:
            self._close()

    def start(self) -> "Explorer":
        """Serve in a background thread; returns self."""
        if self.thread is None:
            self.thread = threading.Thread(
                target=self.server.serve_forever,
                kwargs={"poll_interval": 0.2},
                name="mjx-balance-explore",
                daemon=True,
            )
            self.thread.start()
        return self

    def stop(self) -> None:
        """Stop serving (a run under way is not kept) and free the port."""
        if self.thread is not None:
            self.server.shutdown()
            self.thread.join()
            self.thread = None
        self._close()

    def _close(self) -> None:
        self.runs.close()
        self.server.server_close()  # no new connection
        self.server.wait_answered()  # the requests under way end (Server)

    def __enter__(self) -> "Explorer":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def __repr__(self) -> str:
        return f"<Explorer of {self.folder.shown!r} at {self.url}>"

    def _repr_html_(self) -> str:
        import html

        return (
            f'<a href="{self.url}" target="_blank">{html.escape(self.url)}</a> explores '
            f"{html.escape(self.folder.shown)} (<code>.stop()</code> ends it)"
        )
