"""The page's local web server: the standard library's ``http.server``, on 127.0.0.1 only.

Everything it serves ships in the package (``carbody/annotate/static/``: one HTML page, one
script, one style sheet; no CDN, nothing fetched from elsewhere) or comes from the session: the
photo (upright, as the fit reads it), the session's state as JSON, and a reconstruction's
pictures. Each request is one call of :class:`~carbody.annotate.session.AnnotationSession`.

Requests that change anything (``POST``) must carry the session's token, which only the page
served here knows, and every request must name this server as its host: another web site open
in the same browser can neither drive the page nor read it (DNS rebinding).

    GET  /                    the page
    GET  /static/NAME         its script and style sheet
    GET  /photo               the photo
    GET  /api/setup           what does not change: keypoints, reference car, keys, views
    GET  /api/state           the marks, the fit, the keypoint asked
    GET  /api/refined?revision=N   the state once the full fit of revision N lands (or 204)
    POST /api/edit            {op: place|remove|hide|accept, name, uv?} or {op: view, azimuth}
    POST /api/save            {coco?: bool}
    POST /api/reconstruct     {folder?: str}
    GET  /result/NAME         overlay.png, body.png of the last reconstruction
"""
from __future__ import annotations

import json
import secrets
import threading
import time
from functools import cached_property
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from carbody.errors import CarbodyError

#: The only address the server listens on.
HOST = "127.0.0.1"

#: Files of ``static/`` the server hands out, with their types.
STATIC_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
                ".css": "text/css; charset=utf-8", ".svg": "image/svg+xml", ".png": "image/png"}

#: Pictures of a reconstruction the page shows.
RESULT_FILES = ("overlay.png", "body.png")

#: Views the user can pick before a fit (degrees): the car's four sides and four corners.
VIEW_CHOICES = (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0)

#: The keys the page answers, as it lists them.
KEYS = (("click", "place the keypoint asked"),
        ("drag", "move a mark or a ghost; elsewhere: pan"),
        ("wheel", "zoom"),
        ("Enter", "accept the selected ghost"),
        ("H", "hidden: the photo does not show it"),
        ("N / P", "next / previous keypoint"),
        ("Backspace", "remove the selected mark"),
        ("S", "save"),
        ("F", "fit the photo to the window"))


def static_file(name: str) -> bytes:
    """A file of the page (``carbody/annotate/static/NAME``)."""
    return resources.files("carbody.annotate").joinpath("static", name).read_bytes()


def static_names() -> list[str]:
    return sorted(p.name for p in resources.files("carbody.annotate").joinpath("static").iterdir()
                  if Path(p.name).suffix in STATIC_TYPES)


def page_setup(session) -> dict:
    """What the page needs once: the keypoints (names, twins, descriptions), the reference car
    (the library's mean, normalised units) and its curves, the keys and the views to pick."""
    from carbody.annotate.guide import reference_car
    from carbody.fit import keypoint_slots
    from carbody.topology import load_topology

    topo = load_topology()
    slots = keypoint_slots()
    described = {k.name: k for k in topo.keypoints}
    keypoints = []
    for name, slot in slots.items():
        k = described[name.removesuffix("_right")]
        side = "centre" if k.on_symmetry_plane else ("right" if slot.is_mirror else "left")
        keypoints.append({"name": name, "id": k.id, "label": k.name.replace("_", " "), "side": side,
                          "description": k.description, "point_index": slot.point_index,
                          "twin": None if k.on_symmetry_plane else (k.name if slot.is_mirror else k.mirror_name)})
    central = [c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions for c in topo.curves]
    return {"image_size": list(session.image_size), "image": session.sheet.image,
            "keypoints": keypoints, "min_marks": 5,
            "reference": {"control_points": [[round(float(v), 1) for v in p] for p in reference_car()],
                          "central_curves": central},
            "keys": [list(k) for k in KEYS], "views": list(VIEW_CHOICES),
            "output": str(session.output)}


class AnnotationServer(ThreadingHTTPServer):
    """The HTTP server of one :class:`~carbody.annotate.session.AnnotationSession`."""

    daemon_threads = True

    def __init__(self, session, port: int = 0):
        self.session = session
        self.token = secrets.token_urlsafe(16)
        super().__init__((HOST, port), _Handler)

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.server_address[1]}/"

    @cached_property
    def photo(self) -> tuple[bytes, str]:
        """The photo as the page shows it: upright (as the marks' pixels are), PNG or JPEG."""
        import cv2

        bgr = self.session.rgb[..., ::-1]
        if self.session.image_path.suffix.lower() in (".jpg", ".jpeg"):
            ok, data = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 95])
            return data.tobytes(), "image/jpeg"
        ok, data = cv2.imencode(".png", bgr)
        return data.tobytes(), "image/png"

    def serve_in_thread(self) -> threading.Thread:
        """Serve in a daemon thread (tests, the benchmark); ``shutdown()`` stops it."""
        thread = threading.Thread(target=self.serve_forever, daemon=True, name="carbody-annotate")
        thread.start()
        return thread


class _Handler(BaseHTTPRequestHandler):
    server: AnnotationServer
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args) -> None:  # quiet: the terminal shows the URL only
        pass

    # ---- plumbing

    def _send(self, status: int, body: bytes = b"", kind: str = "application/json") -> None:
        self.send_response(status)
        if getattr(self, "_started_cpu", None) is not None:
            # what answering took this server's thread (the fit, the page's state, the JSON)
            self.send_header("X-Carbody-CPU-ms", f"{(time.thread_time() - self._started_cpu) * 1000.0:.1f}")
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, data, status: int = 200) -> None:
        self._send(status, json.dumps(data).encode())

    def _error(self, status: int, message: str) -> None:
        self._json({"error": message}, status)

    def _host_ok(self) -> bool:
        port = self.server.server_address[1]
        return self.headers.get("Host", "") in (f"{HOST}:{port}", f"localhost:{port}")

    def _body(self) -> dict:
        length = int(self.headers.get("Content-Length") or 0)
        data = json.loads(self.rfile.read(length) or b"{}") if length else {}
        if not isinstance(data, dict):
            raise ValueError("expected a JSON object")
        return data

    # ---- GET

    def do_GET(self) -> None:
        self._started_cpu = None  # (one handler serves a kept-alive connection's every request)
        if not self._host_ok():
            return self._error(HTTPStatus.FORBIDDEN, "wrong host")
        url = urlsplit(self.path)
        path, query = url.path, parse_qs(url.query)
        session = self.server.session
        if path in ("/", "/index.html"):
            page = static_file("index.html").decode().replace("{{TOKEN}}", self.server.token)
            return self._send(200, page.encode(), STATIC_TYPES[".html"])
        if path.startswith("/static/"):
            name = path.removeprefix("/static/")
            if name not in static_names():
                return self._error(HTTPStatus.NOT_FOUND, "no such file")
            return self._send(200, static_file(name), STATIC_TYPES[Path(name).suffix])
        if path == "/photo":
            data, kind = self.server.photo
            return self._send(200, data, kind)
        if path == "/api/setup":
            return self._json(page_setup(session))
        if path == "/api/state":
            return self._json(session.state())
        if path == "/api/refined":
            try:
                revision = int(query.get("revision", ["-1"])[0])
            except ValueError:
                return self._error(HTTPStatus.BAD_REQUEST, "revision must be a number")
            state = session.wait_refined(revision, timeout=15.0)
            return self._send(HTTPStatus.NO_CONTENT) if state is None else self._json(state)
        if path.startswith("/result/"):
            name = path.removeprefix("/result/")
            folder = session.reconstruction.folder
            if name not in RESULT_FILES or session.reconstruction.state != "done" or not folder:
                return self._error(HTTPStatus.NOT_FOUND, "no such picture")
            return self._send(200, (Path(folder) / name).read_bytes(), STATIC_TYPES[".png"])
        return self._error(HTTPStatus.NOT_FOUND, "not found")

    do_HEAD = do_GET

    # ---- POST

    def do_POST(self) -> None:
        self._started_cpu = time.thread_time()
        if not self._host_ok() or self.headers.get("X-Carbody-Token") != self.server.token:
            return self._error(HTTPStatus.FORBIDDEN, "this page's token is missing")
        session = self.server.session
        try:
            body = self._body()
            path = urlsplit(self.path).path
            if path == "/api/edit":
                return self._json(_edit(session, body))
            if path == "/api/save":
                files = session.save(bool(body["coco"]) if "coco" in body else None)
                return self._json({"saved": [str(f) for f in files], "state": session.state()})
            if path == "/api/reconstruct":
                return self._json(session.start_reconstruction(body.get("folder") or None))
            return self._error(HTTPStatus.NOT_FOUND, "not found")
        except CarbodyError as exc:
            return self._error(HTTPStatus.UNPROCESSABLE_ENTITY, str(exc))
        except (ValueError, KeyError, TypeError) as exc:
            return self._error(HTTPStatus.BAD_REQUEST, f"bad request: {exc}")


def _edit(session, body: dict) -> dict:
    """One edit of the marks (``/api/edit``)."""
    op = body.get("op")
    if op == "view":
        return session.pick_view(float(body["azimuth"]))
    name = str(body["name"])
    if op == "place":
        u, v = body["uv"]
        return session.place(name, (float(u), float(v)))
    if op == "remove":
        return session.remove(name)
    if op == "hide":
        return session.hide(name)
    if op == "accept":
        return session.accept(name)
    raise ValueError(f"unknown edit {op!r}")


def serve(session, port: int = 0, open_browser: bool = True, out=None) -> None:
    """Serve ``session``'s page until interrupted (Ctrl+C), opening the browser on it.

    Raises:
        AnnotationError: the port cannot be listened on.
    """
    import sys
    import webbrowser

    from carbody.errors import AnnotationError

    out = out or sys.stdout
    try:
        server = AnnotationServer(session, port)
    except OSError as exc:
        raise AnnotationError(f"cannot listen on {HOST}:{port} ({exc.strerror or exc})") from None
    print(f"carbody annotate: {server.url}  (marks saved to {session.output}; Ctrl+C to stop)", file=out, flush=True)
    if open_browser:
        webbrowser.open(server.url)
    if threading.current_thread() is threading.main_thread():
        import signal

        def stop(signum, frame):  # a polite kill stops as Ctrl+C does: the worker ended too
            raise KeyboardInterrupt

        signal.signal(signal.SIGTERM, stop)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
        session.close()
