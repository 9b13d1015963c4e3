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
