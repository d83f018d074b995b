"""``rasm run APP --dashboard [PORT]``: the report's views live, on 127.0.0.1.

:func:`serve` attaches to a platform before it runs; every trace record the loop emits updates a
:class:`~rasm.report.model.TraceModel` (on the loop thread, under a lock), the Trustworthiness
Checker's verdicts extend the property timelines, and the building blocks' modes are read from
the State Manager. Browsers get the page at ``/`` and follow ``/events`` (server-sent events:
one JSON model per message, at most ``refresh`` seconds apart)::

    platform = Platform(load_manifest("examples/hotbox"))
    platform.build()
    dashboard = serve(platform, 8050)
    try:
        platform.run(60)
    finally:
        dashboard.close()

Only the loopback interface is served: the dashboard has no authentication.
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time as _time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from rasm.errors import PlatformError
from rasm.properties.loader import signals_of
from rasm.report.model import TraceModel
from rasm.report.page import plotly_js, render_page
from rasm.report.verdicts import VerdictTimeline

if TYPE_CHECKING:
    from rasm.platform.assembly import ManagingSide
    from rasm.platform.platform import Platform

__all__ = ["Dashboard", "HOST", "serve"]

HOST = "127.0.0.1"
_log = logging.getLogger("rasm.report.dashboard")


class Dashboard:
    """The live model of one running platform, and the HTTP server that shows it."""

    def __init__(
        self,
        platform: Platform,
        port: int = 8050,
        *,
        refresh: float = 0.5,
        max_points: int = 5000,
    ) -> None:
        self.platform = platform
        self.refresh = refresh
        self.model = TraceModel(max_points=max_points)
        self.timelines: dict[str, VerdictTimeline] = {}
        self.modes: dict[str, str] = {}
        self.status = "starting"
        self._cond = threading.Condition()
        self._version = 0
        self._cache: tuple[int, str] = (-1, "")
        self._verdicts: list[Any] = []  # verdicts not yet on a timeline (loop thread only)
        self._modes_read = 0.0
        self._streams = 0
        self._closed = False
        self._properties()
        self._read_modes()
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise PlatformError(f"dashboard: port {port!r} is not a TCP port (0 to 65535)")
        try:
            self.server = _Server((HOST, port), _Handler, self)
        except OSError as exc:
            raise PlatformError(
                f"dashboard: cannot listen on {HOST}:{port} ({exc.strerror or exc}); "
                "choose another port with --dashboard PORT"
            ) from None
        self.port = self.server.server_address[1]
        self.url = f"http://{HOST}:{self.port}/"
        self._thread = threading.Thread(
            target=self.server.serve_forever, name="rasm-dashboard", daemon=True
        )
        self._thread.start()
        platform.on_record.append(self.on_record)
        platform.on_verdict.append(self.on_verdict)

    def _managing(self) -> ManagingSide | None:
        """The run's managing side, with its Trustworthiness Checker (None: managed only)."""
        return self.platform.assembly.managing

    # ------------------------------------------------------------------ the loop's side

    def _properties(self) -> None:
        # verdicts carry the property's name only: two files' properties of one name share a row
        side = self._managing()
        for monitor in side.trustworthiness_checker.monitors if side is not None else ():
            for prop in monitor.spec.properties:
                timeline = self.timelines.get(prop.name)
                if timeline is None:
                    self.timelines[prop.name] = VerdictTimeline(
                        prop.name,
                        str(prop.location),
                        sorted(signals_of(prop.formula)),
                        max_violations=500,
                    )
                else:
                    timeline.source += f", {prop.location}"
                    timeline.name = f"{prop.name} (in {timeline.source.count(',') + 1} files)"
                    timeline.reads = sorted({*timeline.reads, *signals_of(prop.formula)})

    def _read_modes(self) -> None:
        self.modes = dict(self.platform.assembly.state_manager.get_status())
        self._modes_read = _time.monotonic()

    def on_verdict(self, verdict: Any) -> None:
        """``platform.on_verdict`` observer (loop thread): held until the record it judged."""
        self._verdicts.append(verdict)

    def _take_verdicts(self) -> None:
        verdicts, self._verdicts = self._verdicts, []
        for verdict in verdicts:
            timeline = self.timelines.get(verdict.property)
            if timeline is not None:
                timeline.add(verdict.time, verdict.value, verdict.error, verdict.index)

    def _name_missing(self) -> None:
        """The signals each property never judged waits for, and the antecedents that never
        held, as the checker says at the end."""
        side = self._managing()
        if side is None:
            return
        tc = side.trustworthiness_checker
        for name, timeline in self.timelines.items():
            if not timeline.judged:
                timeline.outcome.missing = tc.missing(name)
            outcome = tc.outcomes.get(name)
            if outcome is not None:
                timeline.outcome.vacuous = outcome.vacuous

    def on_record(self, time: float, record: dict[str, Any]) -> None:
        """``platform.on_record`` observer: runs on the loop thread for every trace record."""
        with self._cond:
            self.status = "running"
            self.model.add(time, record)
            self._take_verdicts()
            if _time.monotonic() - self._modes_read >= 0.1:
                self._read_modes()
            self._version += 1
            self._cond.notify_all()

    # ------------------------------------------------------------------ the browser's side

    def snapshot(self) -> tuple[int, str]:
        """The current model as JSON, and its version (serialised once per version).

        Only the copy is taken under the lock: the loop thread waits for that, not for JSON.
        """
        with self._cond:
            if self._cache[0] == self._version:
                return self._cache
            version, model = self._version, self._model()
        text = json.dumps(_json_safe(model), separators=(",", ":"), allow_nan=False)
        with self._cond:
            if self._cache[0] < version:
                self._cache = (version, text)
        return version, text

    def _model(self) -> dict[str, Any]:
        p = self.platform
        name = p.manifest.name
        data = self.model.to_dict()
        data["properties"] = {
            "files": [],
            "timelines": [t.to_dict() for t in self.timelines.values()],
            "note": "No properties: the Trustworthiness Checker of this run checks none.",
        }
        data["source"] = f"{name} on the {p.clock_kind} clock"
        data["live"] = True
        data["status"] = self.status
        data["modes"] = self.modes
        transport = p.transport_url or "local"
        data["nodes"] = {
            "remote": [],
            "note": f"single process: no remote nodes (transport {transport}, "
            f"role {p.options.role})",
        }
        data["missing"] = []
        return data

    def page(self) -> str:
        name = self.platform.manifest.name
        return render_page(
            None, title=f"rasm dashboard: {name}", events_url="/events", plotly_url="/plotly.js"
        )

    def stream(self, write: Any) -> None:
        """Send the model to one browser each time it changes, until the run finishes."""
        sent = -1
        with self._cond:
            self._streams += 1
        try:
            while True:
                with self._cond:
                    self._cond.wait_for(
                        lambda sent=sent: self._version != sent or self._closed, timeout=10.0
                    )
                    finished = self.status == "finished"
                if self._version == sent and not finished:
                    write(b": keep-alive\n\n")
                    continue
                sent, data = self.snapshot()
                write(f"data: {data}\n\n".encode())
                if finished:
                    return
                with self._cond:  # at most one message every `refresh` seconds
                    self._cond.wait_for(lambda: self._closed, timeout=self.refresh)
        finally:
            with self._cond:
                self._streams -= 1
                self._cond.notify_all()

    # ------------------------------------------------------------------ ending

    def finish(self) -> None:
        """Mark the run finished: browsers get the final model and stop following."""
        with self._cond:
            self._read_modes()
            self._take_verdicts()  # the end-of-run verdicts (the loop thread is done)
            self._name_missing()
            self.status = "finished"
            self._version += 1
            self._cond.notify_all()

    def hold(self) -> None:
        """Finish, then keep showing the finished run until Ctrl-C (or :meth:`close` from
        another thread), then close. For ``rasm run --dashboard`` at an interactive terminal."""
        self.finish()
        try:
            self._thread.join()  # until the server stops
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def close(self, timeout: float = 2.0) -> None:
        """Finish, let the browsers have the final model (``timeout`` at most), stop serving."""
        with self._cond:
            if self._closed:
                return
        self.finish()
        with self._cond:
            self._cond.wait_for(lambda: self._streams == 0, timeout=timeout)
            self._closed = True
            self._cond.notify_all()
        if self.on_record in self.platform.on_record:
            self.platform.on_record.remove(self.on_record)
        if self.on_verdict in self.platform.on_verdict:
            self.platform.on_verdict.remove(self.on_verdict)
        self.server.shutdown()
        self.server.server_close()
        self._thread.join(timeout)

    def __enter__(self) -> Dashboard:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], handler: type, dashboard: Dashboard) -> None:
        self.dashboard = dashboard
        super().__init__(address, handler)


class _Handler(BaseHTTPRequestHandler):
    server: _Server

    def do_GET(self) -> None:  # noqa: N802 - the http.server protocol
        dashboard = self.server.dashboard
        path = urlsplit(self.path).path
        if path == "/":
            self._send(200, "text/html; charset=utf-8", dashboard.page().encode())
        elif path == "/plotly.js":
            body = plotly_js().encode()
            self._send(200, "text/javascript; charset=utf-8", body, cache=True)
        elif path == "/model.json":
            self._send(200, "application/json", dashboard.snapshot()[1].encode())
        elif path == "/events":
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-cache")
            self.end_headers()

            def write(chunk: bytes) -> None:
                self.wfile.write(chunk)
                self.wfile.flush()

            try:
                dashboard.stream(write)
            except (BrokenPipeError, ConnectionResetError):
                pass  # the browser went away
        else:
            self._send(404, "text/plain; charset=utf-8", b"not found\n")

    def _send(self, status: int, kind: str, body: bytes, *, cache: bool = False) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "max-age=3600" if cache else "no-cache")
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - base signature
        _log.debug("%s " + format, self.address_string(), *args)


def serve(platform: Platform, port: int = 8050, **options: Any) -> Dashboard:
    """Serve ``platform``'s dashboard on 127.0.0.1:``port`` (0: any free port).

    Call it after ``platform.build()`` and before ``platform.run(...)``; call ``close()`` on the
    result when the run is over. Raises :class:`~rasm.errors.PlatformError` if the port is taken.
    """
    if not platform.built:
        platform.build()
    return Dashboard(platform, port, **options)
