"""Mutated inputs for the fuzz tests, as Hypothesis strategies: creature files derived from the
built-ins (and, in ``tests/library``, gait exports derived from a valid one), mutated the way a
careless or hostile user would: values of the wrong type or container, numbers that overflow or
vanish (integers too large for a float, or for Python to read), deep nesting, odd keys (newlines,
escape sequences, long dotted keys, too many keys), names with spaces around them, deleted, added and duplicated fields, and
raw-text damage (truncation, stray lines).

The tests run a bounded, seeded number of examples; a larger campaign, with counts of each
outcome, is ``python -m tests.fuzz --creatures 20000`` (see :func:`main`).
"""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Iterator
from typing import Any

import tomlkit
from hypothesis import strategies as st

from sanlab.creature import _toml, builtin_names, read_source

FIELDS = sorted(
    _toml.TOP | _toml.WORLD | _toml.GROUND | set().union(*_toml.TERRAIN.values()) | _toml.FOLLOW | _toml.SAN
    | _toml.EVALUATION | _toml.LINK | _toml.SPRING | _toml.LIMIT | _toml.FRICTION | _toml.POINT
    | set().union(*_toml.SENSOR.values()) | set().union(*_toml.ACTUATOR.values()) | _toml.SPRINGS | {"type", "kind"}
)
NUMBERS = [
    0, 1, -1, 2, 7, 40, 2**31, 2**63 - 1, 2**64, -(2**70), 10**30, 0.0, -0.0, 0.5, -3.5, 1e-300, 1e-12, 1e-9, 1e-5,
    1e5, 1e6, 1e7, 1e12, 3.5e38, 1e39, 1e200, -1e200, math.inf, -math.inf, math.nan,
    10**309, -(10**400),  # integers too large for a float: compared exactly, never converted (issue 33)
]
STRINGS = [
    "", " ", "touch", "angle", "tilt", "eye", "length", "angular", "linear", "segment", "polygon", "point", "flat",
    "hill", "rough", "slope", "vertical", "horizontal", "distance", "pursuit", "forward", "L1", "L2", " L2", "body ", "S1",
    "x" * 10_000, "\x1b[2J\x1b[H", "a\nb", "\u202e", "\x9b31m", "\x00", "café", "../../etc/passwd",
]
KEYS = FIELDS + ["mas", "nmae", "a\nb", "\x1b[31mred", "", " ", "type\n", "1", "é"]
SOURCE = "fuzz.toml"


def scalars() -> st.SearchStrategy:
    return st.one_of(
        st.sampled_from(NUMBERS), st.sampled_from(STRINGS), st.booleans(), st.integers(-(10**20), 10**20),
        st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    )


def values() -> st.SearchStrategy:
    pairs = st.lists(st.lists(st.sampled_from([0, 0.1, -0.2, 1e200, 1e39, 1e-300]), min_size=2, max_size=2), max_size=5)
    leaves = st.one_of(scalars(), pairs)
    return st.recursive(leaves, lambda ch: st.lists(ch, max_size=4) | st.dictionaries(st.sampled_from(KEYS), ch, max_size=3),
                        max_leaves=8)


def paths(node: Any, prefix: tuple = ()) -> Iterator[tuple]:
    """Every path (tuple of keys and indices) into a parsed document, the root first."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from paths(v, prefix + (i,))


def _at(node: Any, path: tuple) -> Any:
    for k in path:
        node = node[k]
    return node


@st.composite
def mutated(draw, doc: dict, most: int = 4) -> dict:
    """``doc`` (a parsed document) with 1 to ``most`` mutations."""
    doc = copy.deepcopy(doc)
    for _ in range(draw(st.integers(1, most))):
        where = list(paths(doc))
        path = draw(st.sampled_from(where))
        node = _at(doc, path)
        op = draw(st.sampled_from(["replace", "replace", "scale", "delete", "add", "duplicate", "nest"]))
        if not path and op in ("replace", "scale", "delete", "nest"):
            op = "add"
        parent, key = (_at(doc, path[:-1]), path[-1]) if path else (None, None)
        if op == "replace":
            parent[key] = draw(values())
        elif op == "scale":
            if isinstance(node, (int, float)) and not isinstance(node, bool):
                parent[key] = node * draw(st.sampled_from([0, -1, 1e-9, 1e-3, 10, 1e3, 1e6, 1e30, 1e300]))
            else:
                parent[key] = draw(st.sampled_from(NUMBERS))
        elif op == "delete":
            del parent[key]
        elif op == "add":
            if isinstance(node, dict):
                node[draw(st.sampled_from(KEYS))] = draw(values())
            elif isinstance(node, list):
                node.append(draw(values()) if not node else copy.deepcopy(node[-1]))
        elif op == "duplicate" and isinstance(node, list) and node:
            node.extend(copy.deepcopy(node[:1]) * draw(st.sampled_from([1, 2, 50, 300])))
        elif op == "nest":
            depth = draw(st.sampled_from([2, 10, 100]))
            for _ in range(depth):
                node = [node]
            parent[key] = node
    return doc


def _lines(text: str, draw) -> str:
    lines = text.splitlines()
    op = draw(st.sampled_from(["truncate", "insert", "delete", "deep", "bytes", "key"]))
    if op == "truncate":
        return text[: draw(st.integers(0, len(text)))]
    if op == "insert":
        i = draw(st.integers(0, len(lines)))
        line = draw(st.sampled_from([
            "[[links]]", "[[sensors]]", "[world]", "[world.ground]", "[evaluation]", "[san]", "[[actuators]]",
            'name = "\\u001b[2J"', '"a\\nb" = 1', "dt = 1e-9", "hidden = 1000000", "stiffness = 1e12", "x = 1e39",
            "type = [\"touch\"]", "mass = {}", "points = [[1e200, 0], [0, 1e200]]", "[[links.points]]", "= 3",
            "mass = 1" + "0" * 309, "x = " + "1" * 5000, "mass = 0x" + "f" * 4000,  # beyond a float; beyond int()
        ]))
        return "\n".join(lines[:i] + [line] + lines[i:]) + "\n"
    if op == "delete" and lines:
        i = draw(st.integers(0, len(lines) - 1))
        return "\n".join(lines[:i] + lines[i + 1 :]) + "\n"
    if op == "key":  # a long dotted key, or many keys, in a line of its own
        key = draw(dotted_keys(hi=5_000)) if draw(st.booleans()) else draw(many_keys(hi=30_000))
        i = draw(st.integers(0, len(lines)))
        return "\n".join(lines[:i] + [key[0]] + lines[i:]) + "\n"
    if op == "deep":
        n = draw(st.sampled_from([200, 600, 3000]))
        opener, closer = draw(st.sampled_from([("[", "]"), ("{ a = ", " }")]))
        return text + f"\n[fuzz]\nv = {opener * n}1{closer * n}\n"
    i = draw(st.integers(0, len(text)))
    junk = draw(st.sampled_from(["\x00", "\x1b", "\r", '"', "'''", "[", "]]", "\ufeff", "\\u", "#"]))
    return text[:i] + junk + text[i:]


@st.composite
def dotted_keys(draw, lo: int = 2, hi: int = 30_000) -> tuple[str, int]:
    """(a TOML key of ``lo`` to ``hi`` parts, its parts) in one of the forms TOML writes a key in:
    dotted bare, numeric or quoted parts, spaces around the dots, as a key, a table header, an
    array-of-tables header or inside an inline table (issue 48: the reader was quadratic in them)."""
    n = draw(st.one_of(st.integers(lo, min(hi, 40)), st.integers(lo, hi)))
    part = draw(st.sampled_from(["a", "1", '"a.b"', "'x'", "k-_9", '""']))
    dot = draw(st.sampled_from([".", " . ", "\t.\t"]))
    key = dot.join([part] * n)
    form = draw(st.sampled_from(["{} = 1", "[{}]", "[[{}]]", "v = {{ {} = 1 }}", "[links.{}]"]))
    return form.format(key), n + (form == "[links.{}]")


@st.composite
def many_keys(draw, lo: int = 1, hi: int = 40_000) -> tuple[str, int]:
    """(TOML text of distinct keys, tables or arrays of tables, their parts in all)."""
    n, depth = draw(st.integers(lo, hi)), draw(st.sampled_from([1, 2, 4, 16]))
    form = draw(st.sampled_from(["k{} = 1\n", "[k{}]\n", "[[k{}]]\n", "v{} = {{ a = 1 }}\n"]))
    tail = ".a" * (depth - 1)
    per = depth + (form == "v{} = {{ a = 1 }}\n")
    return "".join(form.format(f"{i}{tail}") for i in range(n // per + 1)), (n // per + 1) * per


def odd_names() -> st.SearchStrategy:
    """Names as MJCF bytes (in an XML attribute): not UTF-8 (Latin-1, a lone continuation byte,
    a truncated sequence, an encoded surrogate) or holding a control or format character as a
    character reference (a newline, a tab, an escape, a C1 control, a bidi override); issue 48:
    each ended in a traceback or an error about a line of a generated file."""
    bad_bytes = st.sampled_from([b"\xe9", b"\x80", b"\xc3", b"\xed\xa0\x80", b"\xff\xfe", b"caf\xe9"])
    controls = st.sampled_from(["&#10;", "&#9;", "&#13;", "&#27;[2J", "&#x85;", "&#x9b;31m", "&#x202e;", "&#x7f;"])
    word = st.sampled_from([b"", b"a", b"leg", b"x y"])
    return st.one_of(
        st.builds(lambda a, x, b: a + x + b, word, bad_bytes, word),
        st.builds(lambda a, x, b: a + x.encode() + b, word, controls, word),
    )


def bad_widths() -> st.SearchStrategy:
    """Picture widths a Gymnasium environment refuses (issue 48: 0 and -5 gave 64 px, 20,000 a
    MemoryError, 100,000 18 GB): outside [64, 4096], or not an integer."""
    return st.one_of(
        st.sampled_from([0, -5, 63, 4097, 20_000, 100_000, 2**63, -(2**70), 640.0, 1e9, math.nan, "640", None, True, [640]]),
        st.integers(max_value=63), st.integers(min_value=4097),
    )


def huge_ints() -> st.SearchStrategy:
    """Integers too large for a float64 (``10**400``), either sign: np.asarray(..., float)
    raises OverflowError on them, not ValueError."""
    return st.builds(lambda m, neg: -m if neg else m, st.integers(min_value=2**1024, max_value=10**5000), st.booleans())


@st.composite
def page_damage(draw, pages: int, page_size: int = 4096) -> list[tuple[int, int, int]]:
    """(offset, byte, count) writes that damage a library file of ``pages`` pages (never the
    first, the header: a file without one is refused as no database at all): whole pages
    overwritten, a page's header or cells, single bytes changed (issue 48: `sanlab search` then
    wrote into such a file)."""
    out = []
    for _ in range(draw(st.integers(1, 4))):
        page = draw(st.integers(1, pages - 1)) * page_size
        fill = draw(st.sampled_from([0x00, 0xFF, 0xAA, 0x0D]))
        kind = draw(st.sampled_from(["page", "header", "cells", "byte"]))
        if kind == "page":
            out.append((page, fill, page_size))
        elif kind == "header":
            out.append((page, fill, draw(st.integers(1, 12))))
        elif kind == "cells":
            out.append((page + draw(st.integers(12, page_size - 64)), fill, draw(st.integers(1, 64))))
        else:
            out.append((page + draw(st.integers(0, page_size - 1)), draw(st.integers(0, 255)), 1))
    return out


@st.composite
def creature_texts(draw) -> str:
    """A creature file's text: a built-in, mutated as a document (mostly) or as text."""
    text, _ = read_source(draw(st.sampled_from(builtin_names())))
    if draw(st.integers(0, 3)) == 0:
        return _lines(text, draw)
    doc = draw(mutated(tomllib.loads(text)))
    try:
        return tomlkit.dumps(doc)
    except Exception:  # what tomlkit cannot write (too deep for it) is damaged as text
        return _lines(text, draw)


def main(argv: list[str] | None = None) -> int:
    """A larger campaign: ``python -m tests.fuzz [--creatures N] [--exports N] [--seed S]``;
    prints how many inputs were tried, accepted, refused with the documented one-line error, and
    anything else (which must be 0)."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--creatures", type=int, default=20_000)
    ap.add_argument("--exports", type=int, default=0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    bad = 0
    if args.creatures:
        from tests.creature.test_fuzz import campaign

        counts = campaign(args.creatures, args.seed)
        print("creature files:", dict(counts))
        bad += counts["other"]
    if args.exports:
        from tests.library.test_fuzz_import import campaign as exports

        counts = exports(args.exports, args.seed)
        print("gait exports:", dict(counts))
        bad += counts["other"]
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
