"""The studio's web application (Starlette): static page, downloads, and one WebSocket.

HTTP:
    GET /                       the page (sanlab/studio/static/index.html)
    GET /static/...             its modules and style sheet
    GET /api/export?gait=ID     a gait as `sanlab export` writes it (JSON download)
    GET /files/TOKEN            a file rendered on request (GIF, MP4, PNG)

WebSocket /ws, JSON text messages. A request is ``{"id": 7, "op": "runs", ...arguments}``; its
reply is ``{"type": "reply", "id": 7, "ok": true, "data": ...}`` or ``{"type": "reply", "id": 7,
"ok": false, "error": "one line"}`` (``id`` null when the message was too malformed to have one).
A message without an id is a notification (e.g. the follow point, 60 times a second): it is
answered only if it fails. Requests are served concurrently; replies may come in any order. The
server also pushes:

    {"type": "library", "runs": [[run_id, status, count, trials], ...],
     "designs": [[design_id, status, scores], ...]}                 the library changed
    {"type": "job", "job": {...}}                                   a search or tuning progressed
    {"type": "live.frames", ...} / {"type": "live.stats", ...} / {"type": "live.reset", ...}

A job's status is queued, running, done, failed, or (after ``{"op": "job.cancel", "job": ID}``)
cancelling, then cancelled: the batch in flight is committed and the run left interrupted; the
job's ``resume`` is then the command that carries it on.

A failed request changes nothing and the connection stays open. What one message can cost is
bounded: at most MAX_MESSAGE characters (a frame of over MAX_FRAME bytes closes the connection
with 1009, as a text frame that is not UTF-8 closes it with 1007), at most MAX_IN_FLIGHT requests
of one page at once (more are answered "busy"), and a creature file's text within
service.MAX_CREATURE_BYTES and the format's limits (docs/studio.md, "Limits").

Only the page's own origin may open the WebSocket, and while the studio listens on a loopback
address only requests addressed to a loopback name are served (against DNS rebinding): another
web site open in the same browser cannot drive the studio.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import secrets
import shutil
import sys
import tempfile
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import asynccontextmanager
from importlib import resources
from typing import Any, Callable
from urllib.parse import urlsplit

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from sanlab.studio.service import Service, StudioError

log = logging.getLogger("sanlab.studio")

LOOPBACK_NAMES = ["127.0.0.1", "localhost", "::1", "[::1]"]
MAX_MESSAGE = 1 << 20  # characters of one WebSocket message (an uploaded creature file fits easily)
# Bytes of one WebSocket frame the server receives at all (uvicorn's ws_max_size; beyond it the
# connection is closed with 1009): a message of MAX_MESSAGE characters takes at most 4 bytes each.
MAX_FRAME = 4 * MAX_MESSAGE
# Requests of one page served at once; more are answered "busy" at once, so that a flood of large
# messages holds at most this many (each at most MAX_FRAME bytes and what its request costs).
MAX_IN_FLIGHT = 16
LIVE_LEAD = 0.3  # s of simulated time live mode may run ahead of the wall clock (the page's buffer)
PROGRESS_EVERY = 0.2  # s between two progress pushes of one job
MAX_INT = (1 << 63) - 1  # the largest integer argument a request may carry

_NO = object()

# op: {argument: (accepted types, required)}
OPS: dict[str, dict[str, tuple[tuple[type, ...], bool]]] = {
    "hello": {},
    "runs": {},
    "run": {"run": ((str,), True)},
    "top": {"run": ((str,), True), "n": ((int,), False)},
    "modes": {"run": ((str,), True), "n": ((int,), False)},
    "archive": {"run": ((str,), True)},
    "designs": {},
    "design": {"design": ((str,), True)},
    "playback": {"gait": ((str,), True)},
    "render": {"gait": ((str,), True), "kind": ((str,), True)},
    "check": {"text": ((str,), True), "filename": ((str,), False)},
    "search": {"creature": ((str,), False), "text": ((str,), False), "filename": ((str,), False),
               "controllers": ((int,), False), "seconds": ((int, float), False), "seed": ((int,), False)},
    "tune": {"gait": ((str,), True), "method": ((str,), False), "trials": ((int,), False),
             "seed": ((int,), False), "terrain": ((str,), False)},
    "jobs": {},
    "job.cancel": {"job": ((str,), True)},
    "live.start": {"gait": ((str,), True), "terrain": ((str,), False)},
    "live.follow": {"x": ((int, float), True), "y": ((int, float), True)},
    "live.terrain": {"terrain": ((str,), True)},
    "live.stop": {},
}


class BadRequest(Exception):
    """A malformed message (one line)."""


def parse(text: Any) -> tuple[Any, str, dict]:
    """(id, op, arguments) of a request message; BadRequest naming the first fault. The id is
    returned even when the rest is wrong, so that the error can answer the right request."""
    if not isinstance(text, str):
        raise BadRequest("expected a JSON text message, got binary data")
    if len(text) > MAX_MESSAGE:
        raise BadRequest(f"message too large ({len(text)} bytes; at most {MAX_MESSAGE})")
    try:
        msg = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as e:
        raise BadRequest(f"not JSON: {getattr(e, 'msg', 'too deeply nested')} at character {getattr(e, 'pos', 0)}") from None
    except ValueError:  # not a JSONDecodeError: int() refuses a number of more than 4300 digits
        raise BadRequest(f"not JSON this server reads: a number of more than {sys.get_int_max_str_digits()} digits") from None
    if not isinstance(msg, dict):
        raise BadRequest(f"expected a JSON object like {{\"id\": 1, \"op\": \"runs\"}}, got {type(msg).__name__}")
    rid = msg.get("id")
    if rid is not None and (isinstance(rid, bool) or not isinstance(rid, (int, str)) or len(str(rid)) > 64):
        raise BadRequest("'id' must be a number or a short string")
    op = msg.get("op")
    if not isinstance(op, str) or op not in OPS:
        raise _Bad(rid, f"unknown op {op!r}; expected one of {', '.join(OPS)}")
    spec = OPS[op]
    args = {k: v for k, v in msg.items() if k not in ("id", "op")}
    for k in args:
        if k not in spec:
            raise _Bad(rid, f"{op}: unknown argument {k!r}" + (f" (expected {', '.join(spec)})" if spec else ""))
    for k, (types, required) in spec.items():
        if k not in args:
            if required:
                raise _Bad(rid, f"{op}: missing argument {k!r}")
            continue
        v = args[k]
        if isinstance(v, bool) or not isinstance(v, types):
            want = " or ".join("an integer" if t is int else "a number" if t is float else "a string" for t in types)
            raise _Bad(rid, f"{op}: {k!r} must be {want}, not {json.dumps(v)[:40]}")
        if isinstance(v, int) and not -MAX_INT <= v <= MAX_INT:  # beyond any count, seed or coordinate (and a float)
            raise _Bad(rid, f"{op}: {k!r} must be an integer of magnitude below 2^63, not one of {len(str(abs(v)))} digits")
    return rid, op, args


class _Bad(BadRequest):
    def __init__(self, rid: Any, message: str):
        super().__init__(message)
        self.rid = rid


class Connection:
    """One page: its WebSocket (sends serialised by a lock) and its live session."""

    def __init__(self, ws: WebSocket):
        self.ws = ws
        self.lock = asyncio.Lock()
        self.live: LiveRunner | None = None
        self.closed = False

    async def send(self, obj: dict) -> None:
        if self.closed:
            return
        text = json.dumps(obj, separators=(",", ":"), allow_nan=False)
        async with self.lock:
            try:
                await self.ws.send_text(text)
            except Exception:  # the page went away mid-send; the receive loop cleans up
                self.closed = True


class LiveRunner:
    """Steps a live session in a worker thread and streams its frames at real time: it runs at
    most LIVE_LEAD of simulated time ahead of the wall clock (the page plays from a buffer),
    and reports the frame rate and simulated-time/real-time ratios once a second."""

    def __init__(self, studio: "Studio", conn: Connection, session):
        self.studio, self.conn, self.session = studio, conn, session
        self.pending_terrain: Any = _NO
        self.task: asyncio.Task | None = None

    def start(self) -> None:
        self.task = asyncio.create_task(self._run())

    def stop(self) -> None:
        if self.task is not None:
            self.task.cancel()

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        pool = self.studio.live_pool
        s = self.session
        wall0 = sim0 = None
        window = {"t": time.monotonic(), "frames": 0, "sim": 0.0, "compute": 0.0}
        try:
            while True:
                if self.pending_terrain is not _NO:
                    kind, self.pending_terrain = self.pending_terrain, _NO
                    await loop.run_in_executor(pool, s.set_terrain, kind)
                    await self.conn.send({"type": "live.reset", **s.describe()})
                    wall0 = None
                chunk = await loop.run_in_executor(pool, s.step)
                now = time.monotonic()
                t = chunk["t"]
                t_end = t[-1] + s.frame_dt
                if wall0 is None:
                    wall0, sim0 = now, t[0]
                await self.conn.send({"type": "live.frames", **chunk})
                window["frames"] += len(t)
                window["sim"] += s.chunk_seconds
                window["compute"] += chunk["compute_s"]
                ahead = (t_end - sim0) - (now - wall0)
                if ahead < -1.0:  # fell far behind (a compilation, a busy machine): don't rush to catch up
                    wall0 = now - (t_end - sim0)
                elif ahead > LIVE_LEAD:
                    await asyncio.sleep(ahead - LIVE_LEAD)
                span = time.monotonic() - window["t"]
                if span >= 1.0:
                    await self.conn.send({
                        "type": "live.stats", "t": t_end,
                        "frames_per_s": window["frames"] / span,  # frames delivered per wall second
                        "ratio": window["sim"] / span,  # simulated s per wall s (paced: about 1)
                        "capacity": window["sim"] / max(window["compute"], 1e-9),  # unpaced ratio
                    })
                    window = {"t": time.monotonic(), "frames": 0, "sim": 0.0, "compute": 0.0}
        except asyncio.CancelledError:
            raise
        except StudioError as e:
            await self.conn.send({"type": "live.error", "error": str(e)})
        except Exception as e:  # keep serving; tell the page
            log.exception("live session failed")
            await self.conn.send({"type": "live.error", "error": f"live mode stopped: {type(e).__name__}: {e}"})


class Jobs:
    """Searches and tunings started from the page, run one at a time in a worker thread (they use
    every core); progress goes to every page through the same reporter callbacks as the CLI's."""

    def __init__(self, studio: "Studio"):
        self.studio = studio
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="studio-job")
        self.jobs: dict[str, dict] = {}
        self._n = 0
        self._control: dict[str, tuple[threading.Event, Future, Callable[..., None]]] = {}  # cancel, future, push

    def list(self) -> list[dict]:
        return list(self.jobs.values())

    def cancel(self, job_id: str) -> dict:
        """Stop a job: a queued one never starts; a running one stops after the batch (a search)
        or round (a tuning) in flight, which is committed, and its run is left "interrupted", so
        that ``sanlab search --resume RUN`` / ``sanlab tune --resume RUN`` carries it on. A job
        that has already ended is returned as it is (cancelling twice is no error)."""
        job = self.jobs.get(job_id)
        if job is None:
            raise StudioError(f"job.cancel: no job {job_id!r}" + (f" (jobs: {', '.join(self.jobs)})" if self.jobs else ""))
        if job["status"] in ("queued", "running"):
            cancel, future, push = self._control[job_id]
            cancel.set()
            job["status"] = "cancelled" if future.cancel() else "cancelling"
            push(True)
        return dict(job)

    def submit(self, kind: str, label: str, fn: Callable[[Callable[[dict], None]], Any]) -> dict:
        self._n += 1
        job = {"id": f"job{self._n}", "kind": kind, "label": label, "status": "queued", "done": 0,
               "total": None, "best": None, "rate": None, "run_id": None, "result": None, "error": None,
               "resume": None, "started": time.time()}
        self.jobs[job["id"]] = job
        loop = asyncio.get_running_loop()
        last = [0.0]
        cancel = threading.Event()

        def push(force: bool = False) -> None:
            now = time.monotonic()
            if force or now - last[0] >= PROGRESS_EVERY:
                last[0] = now
                snapshot = dict(job)
                loop.call_soon_threadsafe(lambda: asyncio.ensure_future(
                    self.studio.broadcast({"type": "job", "job": snapshot})))

        def report(p: dict) -> None:
            job.update({k: v for k, v in p.items() if k in ("run_id", "done", "total", "best", "rate")})
            if cancel.is_set():
                if not p.get("finished"):
                    raise JobCancelled  # the driver marks the run interrupted and re-raises it
            else:
                job["status"] = "running"
            push(force=p.get("done") == p.get("total"))

        def work() -> None:
            if cancel.is_set():  # cancelled as it was about to start
                job["status"] = "cancelled"
                push(True)
                return
            job["status"] = "running"
            push(True)
            try:
                job["result"] = fn(report)
                job["status"] = "done"
            except JobCancelled:
                job["status"] = "cancelled"
                if job["run_id"]:
                    job["resume"] = f"sanlab {kind} --resume {job['run_id']}"
            except StudioError as e:
                job["status"], job["error"] = "failed", str(e)
            except Exception as e:  # the server must keep serving
                log.exception("job %s failed", job["id"])
                job["status"], job["error"] = "failed", f"{type(e).__name__}: {e}"
            push(True)

        self._control[job["id"]] = (cancel, self.pool.submit(work), push)
        return dict(job)


class JobCancelled(Exception):
    """Raised by a cancelled job's progress callback, which the search driver calls after each
    committed batch: the driver then marks the job's run interrupted and re-raises it."""


class Studio:
    """The application's state: the service, the pages connected, jobs, worker pools."""

    def __init__(self, service: Service, *, poll: float = 1.0, local_only: bool = True):
        self.service = service
        self.poll = poll
        self.local_only = local_only
        self.conns: set[Connection] = set()
        self.jobs = Jobs(self)
        self.read_pool = ThreadPoolExecutor(4, thread_name_prefix="studio-read")
        self.compute_pool = ThreadPoolExecutor(1, thread_name_prefix="studio-replay")
        self.live_pool = ThreadPoolExecutor(2, thread_name_prefix="studio-live")
        self.files_dir = tempfile.mkdtemp(prefix="sanlab-studio-")
        self.files: dict[str, str] = {}
        self._fingerprint: Any = None

    async def broadcast(self, obj: dict) -> None:
        for c in list(self.conns):
            await c.send(obj)

    async def watch(self) -> None:
        """Poll the library (a short read, never a lock the writer waits on) and push a change
        to every page: a `sanlab search` or `sanlab design` running in another process shows up
        as it commits."""
        loop = asyncio.get_running_loop()
        while True:
            try:
                fp = await loop.run_in_executor(
                    self.read_pool, lambda: (self.service.fingerprint(), self.service.design_fingerprint()))
                if fp != self._fingerprint:
                    self._fingerprint = fp
                    await self.broadcast({"type": "library", "runs": fp[0], "designs": fp[1]})
            except StudioError as e:
                log.warning("cannot read the library: %s", e)
            await asyncio.sleep(self.poll)

    def close(self) -> None:
        for pool in (self.read_pool, self.compute_pool, self.live_pool):
            pool.shutdown(wait=False, cancel_futures=True)
        self.jobs.pool.shutdown(wait=False, cancel_futures=True)
        shutil.rmtree(self.files_dir, ignore_errors=True)

    # -- requests ----------------------------------------------------------------------------

    async def handle(self, conn: Connection, rid: Any, op: str, args: dict) -> None:
        try:
            data = await self.dispatch(conn, op, args)
        except StudioError as e:
            await conn.send({"type": "reply", "id": rid, "ok": False, "error": str(e)})
            return
        except Exception as e:  # one bad request must not stop the server
            log.exception("request %s failed", op)
            await conn.send({"type": "reply", "id": rid, "ok": False,
                             "error": f"internal error in {op}: {type(e).__name__}: {e}"})
            return
        if rid is not None:  # a message without id is a notification: answered only on error
            await conn.send({"type": "reply", "id": rid, "ok": True, "data": data})

    async def dispatch(self, conn: Connection, op: str, a: dict) -> Any:
        loop = asyncio.get_running_loop()
        svc = self.service

        def read(fn, *args, **kw):
            return loop.run_in_executor(self.read_pool, lambda: fn(*args, **kw))

        def compute(fn, *args, **kw):
            return loop.run_in_executor(self.compute_pool, lambda: fn(*args, **kw))

        if op == "hello":
            return await read(svc.info)
        if op == "runs":
            return await read(svc.runs)
        if op == "run":
            return await read(svc.run, a["run"])
        if op == "top":
            return await read(svc.top, a["run"], a.get("n", 10))
        if op == "modes":
            return await read(svc.modes, a["run"], a.get("n", 12))
        if op == "archive":
            return await read(svc.archive, a["run"])
        if op == "designs":
            return await read(svc.designs)
        if op == "design":
            return await read(svc.design, a["design"])
        if op == "playback":
            return await compute(svc.playback, a["gait"])
        if op == "render":
            path = await compute(svc.render, a["gait"], a["kind"], self.files_dir)
            token = secrets.token_urlsafe(12)
            self.files[token] = path
            return {"url": f"/files/{token}", "name": os.path.basename(path)}
        if op == "check":
            return await read(svc.check_creature, a["text"], a.get("filename", "uploaded.toml"))
        if op == "search":
            prep = await read(lambda: svc.prepare_search(**a))
            args = prep["args"]
            label = f"search {prep['creature']}: {args['controllers']} controllers, seed {args['seed']}"
            return self.jobs.submit("search", label, lambda report: {"run_id": svc.search(args, report)})
        if op == "tune":
            args = await read(lambda: svc.prepare_tune(**a))
            label = f"tune {args['gait']} ({args['method']}, {args['trials']} trials, {args['terrain']})"
            return self.jobs.submit("tune", label, lambda report: {"gait": svc.tune(args, report)})
        if op == "jobs":
            return self.jobs.list()
        if op == "job.cancel":
            return self.jobs.cancel(a["job"])
        if op == "live.start":
            terrain = a.get("terrain") or None
            session = await loop.run_in_executor(self.live_pool, lambda: svc.live(a["gait"], terrain))
            if conn.live is not None:
                conn.live.stop()
            conn.live = LiveRunner(self, conn, session)
            conn.live.start()
            return session.describe()
        if op == "live.stop":  # idempotent: a page leaving live mode twice is no error
            if conn.live is not None:
                conn.live.stop()
                conn.live = None
            return None
        if op in ("live.follow", "live.terrain"):
            if conn.live is None:
                raise StudioError(f"{op}: no live session (start one with live.start)")
            if op == "live.follow":
                conn.live.session.set_follow(a["x"], a["y"])
                return None
            if op == "live.terrain":
                conn.live.session.check_terrain(a["terrain"])  # validate now, apply between two chunks
                conn.live.pending_terrain = a["terrain"]
                return {"terrain": a["terrain"]}
        raise StudioError(f"unknown op {op!r}")  # parse() lets none through


class RefusedRequests:
    """ASGI middleware: a response the server can no longer send is dropped, not a traceback.

    When a request's body is malformed (a chunked POST with a bad chunk size, say), uvicorn
    answers 400 itself, logs one line ("Invalid HTTP request received.") and closes the
    connection, while the application, already started on the request's headers, still sends
    its own response; h11 then raises (LocalProtocolError) inside the application's ``send``,
    and uvicorn logs "Exception in ASGI application" with the whole traceback. Here such a
    ``send`` is swallowed (logged at debug level), every later one of the same response is
    skipped (the client already has its answer), and the request then waits, a second at most,
    for the connection's close to reach it, so that uvicorn does not log the unfinished response
    as an error either."""

    def __init__(self, app: Any):
        self.app = app

    async def __call__(self, scope: dict, receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        dropped = False

        async def guarded(message: dict) -> None:
            nonlocal dropped
            if dropped:
                return
            try:
                await send(message)
            except Exception as e:  # the connection cannot take it: uvicorn answered already
                dropped = True
                log.debug("dropped the response to %s %s: %s: %s", scope.get("method"), scope.get("path"),
                          type(e).__name__, e)

        await self.app(scope, receive, guarded)
        if dropped:
            await _closed(receive, 1.0)


async def _closed(receive: Callable, timeout: float) -> None:
    """Read a request's messages until the server says the client is gone, ``timeout`` s at most."""
    deadline = time.monotonic() + timeout
    with contextlib.suppress(Exception):
        while (left := deadline - time.monotonic()) > 0:
            if (await asyncio.wait_for(receive(), left)).get("type") == "http.disconnect":
                return


def create_app(service: Service, *, poll: float = 1.0, local_only: bool = True) -> Starlette:
    """The ASGI application over ``service``. ``local_only``: serve only requests addressed to
    a loopback name (set it when listening on a loopback address)."""
    studio = Studio(service, poll=poll, local_only=local_only)
    static = resources.files("sanlab.studio") / "static"

    async def index(request: Request) -> Response:
        return FileResponse(str(static / "index.html"), headers={"Cache-Control": "no-cache"})

    async def export(request: Request) -> Response:
        gait = request.query_params.get("gait", "")
        loop = asyncio.get_running_loop()
        try:
            data = await loop.run_in_executor(studio.read_pool, service.export, gait)
        except StudioError as e:
            return JSONResponse({"error": str(e)}, status_code=404)
        name = gait.replace("/", "_").replace("#", "_") + ".json"
        return Response(json.dumps(data, indent=2) + "\n", media_type="application/json",
                        headers={"Content-Disposition": f'attachment; filename="{name}"'})

    async def files(request: Request) -> Response:
        path = studio.files.get(request.path_params["token"])
        if path is None or not os.path.exists(path):
            return JSONResponse({"error": "no such file (rendered files last while the studio runs)"}, status_code=404)
        return FileResponse(path, filename=os.path.basename(path))

    async def ws_endpoint(ws: WebSocket) -> None:
        origin = ws.headers.get("origin")
        if origin is not None and urlsplit(origin).netloc != ws.headers.get("host"):
            await ws.close(code=1008)  # another site's page: refuse
            return
        await ws.accept()
        conn = Connection(ws)
        studio.conns.add(conn)
        tasks: set[asyncio.Task] = set()
        try:
            while True:
                msg = await ws.receive()
                if msg["type"] == "websocket.disconnect":
                    break
                try:
                    rid, op, args = parse(msg.get("text") if msg.get("text") is not None else msg.get("bytes"))
                except BadRequest as e:
                    await conn.send({"type": "reply", "id": getattr(e, "rid", None), "ok": False,
                                     "error": f"malformed message: {e}"})
                    continue
                if len(tasks) >= MAX_IN_FLIGHT:
                    await conn.send({"type": "reply", "id": rid, "ok": False,
                                     "error": f"busy: {len(tasks)} requests of this page are in flight, at most "
                                              f"{MAX_IN_FLIGHT}; send it again once one is answered"})
                    continue
                task = asyncio.create_task(studio.handle(conn, rid, op, args))
                tasks.add(task)
                task.add_done_callback(tasks.discard)
        except WebSocketDisconnect:
            pass
        finally:
            conn.closed = True
            studio.conns.discard(conn)
            if conn.live is not None:
                conn.live.stop()
            for t in tasks:
                t.cancel()

    @asynccontextmanager
    async def lifespan(app):
        watcher = asyncio.create_task(studio.watch())
        try:
            yield
        finally:
            watcher.cancel()
            studio.close()

    middleware = [Middleware(RefusedRequests)]
    if local_only:
        middleware.append(Middleware(TrustedHostMiddleware, allowed_hosts=LOOPBACK_NAMES))
    app = Starlette(
        routes=[
            Route("/", index),
            Route("/api/export", export),
            Route("/files/{token}", files),
            WebSocketRoute("/ws", ws_endpoint),
            Mount("/static", StaticFiles(directory=str(static)), name="static"),
        ],
        middleware=middleware,
        lifespan=lifespan,
    )
    app.state.studio = studio
    return app
