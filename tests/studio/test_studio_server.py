"""The studio's server without a browser: the WebSocket protocol under bad input, what it binds
to, which hosts and origins it serves, and the `sanlab studio` command."""

from __future__ import annotations

import json
import socket
import urllib.error
import urllib.request

import pytest
from typer.testing import CliRunner
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from sanlab.library import Library
from sanlab.studio.app import BadRequest, parse


def ws_url(studio) -> str:
    return studio.url.replace("http://", "ws://") + "ws"


def reply(ws, timeout: float = 60.0) -> dict:
    """The next reply (skipping pushes such as library updates)."""
    while True:
        msg = json.loads(ws.recv(timeout=timeout))
        if msg["type"] == "reply":
            return msg


def fingerprint(db: str) -> list:
    with Library(db) as lib:
        return [(r.run_id, r.status, r.count) for r in lib.runs()]


@pytest.mark.parametrize("text, fault", [
    ("{not json", "not JSON"),
    ("[1, 2]", "expected a JSON object"),
    ('{"id": 1}', "unknown op None"),
    ('{"id": 2, "op": "drop tables"}', "unknown op 'drop tables'"),
    ('{"id": 3, "op": "run"}', "missing argument 'run'"),
    ('{"id": 4, "op": "run", "run": 7}', "'run' must be a string"),
    ('{"id": 5, "op": "top", "run": "ab", "n": true}', "'n' must be an integer"),
    ('{"id": 6, "op": "runs", "evil": 1}', "unknown argument 'evil'"),
    ('{"id": [1], "op": "runs"}', "'id' must be"),
])
def test_parse_names_the_fault(text, fault):
    with pytest.raises(BadRequest) as e:
        parse(text)
    assert fault in str(e.value)


def test_malformed_messages_get_error_replies_and_the_next_request_works(studio, library):
    before = fingerprint(library["db"])
    with connect(ws_url(studio)) as ws:
        ws.send(b"\x00\x01binary")
        r = reply(ws)
        assert r["ok"] is False and "binary" in r["error"] and r["id"] is None
        ws.send("{not json")
        r = reply(ws)
        assert r["ok"] is False and r["error"].startswith("malformed message: not JSON")
        ws.send(json.dumps({"id": 9, "op": "search", "creature": "cart", "controllers": "many"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (9, False) and "'controllers' must be an integer" in r["error"]
        ws.send(json.dumps({"id": 10, "op": "playback", "gait": "deadbeef/1"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (10, False) and "no run 'deadbeef'" in r["error"]
        ws.send(json.dumps({"id": 11, "op": "tune", "gait": f"{library['cart']}/999"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (11, False) and "has 24 evaluations" in r["error"]
        ws.send(json.dumps({"id": 12, "op": "search", "text": "name = [", "filename": "bad.toml"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (12, False) and r["error"].startswith("bad.toml")
        ws.send(json.dumps({"id": 13, "op": "live.follow", "x": 1, "y": 2}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (13, False) and "no live session" in r["error"]
        ws.send(json.dumps({"id": 14, "op": "runs"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (14, True)
        assert {library["cart"], library["fish"].split("/")[0]} <= {x["run_id"] for x in r["data"]}
    assert fingerprint(library["db"]) == before  # no failed request changed the library


def test_a_gait_of_another_library_is_refused(studio, library, tmp_path):
    other = tmp_path / "other.db"
    with Library(str(other)) as lib:
        run = lib.create_run("search", "cart", "name = 'cart'", {}, seed=0, total=1)
    before = fingerprint(library["db"])
    with connect(ws_url(studio)) as ws:
        ws.send(json.dumps({"id": 1, "op": "playback", "gait": f"{run.run_id}/1"}))
        r = reply(ws)
        assert r["ok"] is False and f"no run '{run.run_id}'" in r["error"] and library["db"] in r["error"]
    assert fingerprint(library["db"]) == before


def test_export_over_http(studio, library):
    gait = f"{library['cart']}/1"
    with urllib.request.urlopen(studio.url + f"api/export?gait={gait}") as r:
        data = json.load(r)
    with Library(library["db"]) as lib:
        assert data == lib.export_gait(gait)
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(studio.url + "api/export?gait=nonsense")
    assert e.value.code == 404 and "malformed gait id" in json.load(e.value)["error"]


def _non_loopback_address() -> str | None:
    """An address of this machine other than loopback (None if it has none)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        s.connect(("10.254.254.254", 1))  # no packet is sent: this only picks a route's source
        ip = s.getsockname()[0]
    except OSError:
        return None
    finally:
        s.close()
    return None if ip.startswith("127.") or ip == "0.0.0.0" else ip


def test_by_default_it_listens_on_loopback_only(studio):
    assert studio.host == "127.0.0.1"
    assert {s.getsockname()[0] for s in studio.sockets()} == {"127.0.0.1"}
    ip = _non_loopback_address()
    if ip is None:
        pytest.skip("this machine has no non-loopback address to try")
    with pytest.raises(OSError):
        socket.create_connection((ip, studio.port), timeout=5).close()


def test_other_hosts_and_origins_are_refused(studio):
    req = urllib.request.Request(studio.url, headers={"Host": f"evil.example:{studio.port}"})
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(req)
    assert e.value.code == 400  # DNS rebinding: a page of another site resolved to 127.0.0.1
    with pytest.raises(InvalidStatus):
        connect(ws_url(studio), origin="http://evil.example").close()
    with connect(ws_url(studio), origin=studio.url.rstrip("/")) as ws:  # the page's own origin
        ws.send(json.dumps({"id": 1, "op": "hello"}))
        assert reply(ws)["ok"] is True


def test_studio_command(tmp_path, monkeypatch):
    from sanlab.cli import app

    calls = []
    monkeypatch.setattr("sanlab.studio.server.serve", lambda *a, **k: calls.append(a))
    r = CliRunner().invoke(app, ["studio", "--db", str(tmp_path / "x.db"), "--no-open"])
    assert r.exit_code == 0, r.output
    assert calls == [(str(tmp_path / "x.db"), "127.0.0.1", 8765, False)]
    bad = tmp_path / "notes.txt"
    bad.write_text("hello")
    monkeypatch.undo()
    r = CliRunner().invoke(app, ["studio", "--db", str(bad), "--no-open", "--port", "0"])
    assert r.exit_code == 2
    assert r.output.strip() == f"{bad}: not a database file (it is a text file)"


def test_a_tune_job_reports_the_run_it_writes(library, tmp_path):
    """A tune job, like a search job, says which run it writes, so a page can link to it."""
    import shutil

    from sanlab.studio.service import Service

    db = str(tmp_path / "copy.db")
    shutil.copy(library["db"], db)  # the shared library stays as the other tests expect it
    svc = Service(db)
    args = svc.prepare_tune(gait=f"{library['cart']}/1", trials=2)
    seen: list[dict] = []
    tuned = svc.tune(args, seen.append)
    assert seen and {p["run_id"] for p in seen} == {tuned.split("#")[0]}
    with Library(db) as lib:
        assert lib.get_run(tuned.split("#")[0]).kind == "tune"


def _job_push(ws, job_id: str, statuses: set, timeout: float = 300.0) -> dict:
    """The next pushed state of job ``job_id`` whose status is one of ``statuses``."""
    while True:
        msg = json.loads(ws.recv(timeout=timeout))
        if msg["type"] == "job" and msg["job"]["id"] == job_id and msg["job"]["status"] in statuses:
            return msg["job"]


@pytest.mark.slow  # about 6 s on 2 busy cores (the pre-commit subset leaves it out)
def test_a_cancelled_job_stops_after_its_batch_and_its_run_resumes(library, tmp_path):
    """A running search stops after the batch in flight, which is kept, and leaves its run
    interrupted with the command that carries it on; a queued job never starts; cancelling an
    ended job is no error, an unknown one is; `sanlab search --resume` then finishes the run."""
    import shutil

    from sanlab.cli import app
    from sanlab.studio.server import StudioServer

    db = str(tmp_path / "copy.db")
    shutil.copy(library["db"], db)
    before = {r[0] for r in fingerprint(db)}
    with StudioServer(db, port=0, poll=0.25) as server, connect(ws_url(server)) as ws:
        big = {"op": "search", "creature": "cart", "controllers": 12 * 256, "seconds": 1.0, "seed": 3}
        ws.send(json.dumps({"id": 1, **big}))
        first = reply(ws)["data"]
        ws.send(json.dumps({"id": 2, **big, "seed": 4}))
        queued = reply(ws)["data"]
        assert queued["status"] == "queued"
        # the queued one first: it never runs
        ws.send(json.dumps({"id": 3, "op": "job.cancel", "job": queued["id"]}))
        assert reply(ws)["data"]["status"] == "cancelled"
        while True:  # the first has committed a batch
            job = _job_push(ws, first["id"], {"running"})
            if job["done"]:
                break
        ws.send(json.dumps({"id": 4, "op": "job.cancel", "job": first["id"]}))
        assert reply(ws)["data"]["status"] in ("cancelling", "cancelled")
        job = _job_push(ws, first["id"], {"cancelled", "done", "failed"})
        assert job["status"] == "cancelled" and job["error"] is None
        run_id = job["run_id"]
        assert job["resume"] == f"sanlab search --resume {run_id}"
        ws.send(json.dumps({"id": 5, "op": "job.cancel", "job": first["id"]}))  # again: no error
        r = reply(ws)
        assert r["ok"] and r["data"]["status"] == "cancelled"
        ws.send(json.dumps({"id": 6, "op": "job.cancel", "job": "job99"}))
        r = reply(ws)
        assert not r["ok"] and r["error"].startswith("job.cancel: no job 'job99'")
        ws.send(json.dumps({"id": 7, "op": "jobs"}))
        assert [j["status"] for j in reply(ws)["data"]] == ["cancelled", "cancelled"]
    with Library(db) as lib:
        runs = {r.run_id: r for r in lib.runs()}
        assert set(runs) - before == {run_id}  # the queued job made no run
        kept = lib.count(run_id)
        assert runs[run_id].status == "interrupted" and 0 < kept < 12 * 256 and kept % 256 == 0
    r = CliRunner().invoke(app, ["search", "--resume", run_id, "--db", db])
    assert r.exit_code == 0, r.output
    with Library(db) as lib:
        assert lib.get_run(run_id).status == "done" and lib.count(run_id) == 12 * 256


def test_a_tuning_stopped_by_its_reporter_is_left_interrupted_and_resumes(library, tmp_path):
    """How a tune job is cancelled: its progress callback raises after a round, the tuning run is
    left interrupted, and `sanlab tune --resume` finishes it."""
    import shutil

    from sanlab.cli import app
    from sanlab.studio.app import JobCancelled
    from sanlab.studio.service import Service

    db = str(tmp_path / "copy.db")
    shutil.copy(library["db"], db)
    svc = Service(db)
    args = svc.prepare_tune(gait=f"{library['cart']}/1", trials=24)
    seen: list[dict] = []

    def report(p: dict) -> None:
        seen.append(p)
        if p["done"]:
            raise JobCancelled

    with pytest.raises(JobCancelled):
        svc.tune(args, report)
    run_id = seen[-1]["run_id"]
    with Library(db) as lib:
        assert lib.get_run(run_id).status == "interrupted"
    r = CliRunner().invoke(app, ["tune", "--resume", run_id, "--db", db])
    assert r.exit_code == 0, r.output
    with Library(db) as lib:
        assert lib.get_run(run_id).status == "done"


def test_studio_opens_no_browser_where_there_is_no_display(monkeypatch):
    """Issue 49: on a machine with no display (SSH, a container) the studio needed --no-open."""
    import webbrowser

    import sanlab.studio.server as server

    assert not server.has_display({}, "linux") and not server.has_display({"DISPLAY": ""}, "linux")
    assert server.has_display({"DISPLAY": ":0"}, "linux") and server.has_display({"WAYLAND_DISPLAY": "wayland-0"}, "linux")
    assert server.has_display({}, "darwin") and server.has_display({}, "win32")

    class Quiet:  # a server that stops at once
        url = "http://127.0.0.1:8765/"
        _thread = None
        service = type("S", (), {"path": "x.db"})()

        def __init__(self, *a, **k):
            pass

        def start(self):
            return self

        def stop(self):
            pass

    opened, said = [], []
    monkeypatch.setattr(server, "StudioServer", Quiet)
    monkeypatch.setattr(webbrowser, "open", lambda url: opened.append(url))
    for key in ("DISPLAY", "WAYLAND_DISPLAY", "BROWSER"):
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    server.serve("x.db", echo=said.append)
    assert opened == [] and any("no display here" in s and "http://127.0.0.1:8765/" in s for s in said), said
