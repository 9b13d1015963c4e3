"""The studio under bad input found by a fuzzer (issue 33): numbers too long for Python's int(),
integers beyond any argument's range, and malformed chunked POSTs. Each is answered with an error
and leaves no traceback in the server's log. A studio over an empty library: nothing compiles."""

from __future__ import annotations

import json
import logging
import socket
import time
import urllib.request

import pytest
from websockets.sync.client import connect

from sanlab.studio.app import BadRequest, parse

HUGE = "1" * 5000  # more digits than int() reads (sys.get_int_max_str_digits(): 4300)


@pytest.mark.parametrize("text, fault", [
    ('{"id": 1, "op": "top", "run": "ab", "n": ' + HUGE + "}", "a number of more than 4300 digits"),
    ('{"id": ' + HUGE + ', "op": "runs"}', "a number of more than 4300 digits"),
    ('{"id": 2, "op": "top", "run": "ab", "n": ' + "9" * 400 + "}", "'n' must be an integer of magnitude below 2^63"),
    ('{"id": 3, "op": "live.follow", "x": 1' + "0" * 309 + ', "y": 0}', "'x' must be an integer of magnitude below"),
    ('{"id": 4, "op": "search", "seed": -' + "9" * 20 + "}", "'seed' must be an integer of magnitude below"),
])  # fmt: skip
def test_parse_refuses_numbers_too_long_to_read_or_too_large_to_use(text, fault):
    with pytest.raises(BadRequest) as e:
        parse(text)
    assert fault in str(e.value)
    assert "\n" not in str(e.value) and len(str(e.value)) < 200


def test_parse_still_takes_large_but_usable_integers():
    assert parse('{"id": 5, "op": "top", "run": "ab", "n": 9223372036854775807}')[2] == {"run": "ab", "n": 2**63 - 1}


class Records(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@pytest.fixture(scope="module")
def bare_studio(tmp_path_factory):
    """A studio over an empty library, and the records uvicorn logs while it runs."""
    from sanlab.studio.server import StudioServer

    with StudioServer(str(tmp_path_factory.mktemp("bare") / "gaits.db"), port=0, poll=0.25) as server:
        handler = Records()
        logger = logging.getLogger("uvicorn.error")
        logger.addHandler(handler)
        try:
            yield server, handler
        finally:
            logger.removeHandler(handler)


def test_a_message_with_a_5000_digit_number_is_answered_and_the_connection_stays(bare_studio):
    server, _ = bare_studio
    with connect(server.url.replace("http://", "ws://") + "ws") as ws:
        ws.send('{"id": 1, "op": "top", "run": "ab", "n": ' + HUGE + "}")
        while (r := json.loads(ws.recv(timeout=30)))["type"] != "reply":
            pass  # the library's own news may come first on a busy machine
        assert r["ok"] is False
        assert r["error"] == "malformed message: not JSON this server reads: a number of more than 4300 digits"
        ws.send(json.dumps({"id": 2, "op": "runs"}))  # the same connection still serves
        while (r := json.loads(ws.recv(timeout=30)))["type"] != "reply":
            pass
        assert (r["id"], r["ok"], r["data"]) == (2, True, [])


BODIES = [
    b"zz\r\nhello\r\n0\r\n\r\n",  # a chunk size that is not hexadecimal
    b"-1\r\n",  # a negative one
    b"5\r\nhelloXX0\r\n\r\n",  # a chunk longer than it said
    b"f" * 40 + b"\r\n",  # a size too large to be read
]


def test_a_malformed_chunked_post_gets_400_and_leaves_no_traceback(bare_studio):
    server, log = bare_studio
    log.records.clear()
    tried = 0
    for path in ("/", "/api/export?gait=ab/1", "/ws"):
        for body in BODIES:
            with socket.create_connection(("127.0.0.1", server.port), timeout=10) as c:
                c.sendall(b"POST " + path.encode() + b" HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\n"
                          + body)
                answer = c.recv(200)
                while chunk := c.recv(4096):  # the server closes the connection
                    answer += chunk
            assert answer.startswith(b"HTTP/1.1 400 Bad Request"), (path, body, answer[:100])
            tried += 1
    with urllib.request.urlopen(server.url, timeout=30) as r:  # and it serves the next request
        assert r.status == 200
    time.sleep(1.5)  # what uvicorn logs once each refused request's application has returned
    seen = [(rec.levelname, rec.getMessage()) for rec in log.records]
    assert seen == [("WARNING", "Invalid HTTP request received.")] * tried, seen
    assert not any(rec.exc_info for rec in log.records)
