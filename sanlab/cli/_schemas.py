"""The JSON Schemas of every ``--json`` output (docs/json.md describes them field by field).

Each file ``sanlab/schemas/<name>.json`` (package data, no module) is one record; an output carries ``"schema": "sanlab/<name>/1"``
as its first field (a list output: each element), so that a consumer can tell what it reads and
which version. ``gait-row`` is the one record nested in others (search's and show's ``top``)
rather than printed alone. The version goes up when a field changes meaning or goes away; a
new field does not change it.

:func:`validate` checks an output against its schema with the ``jsonschema`` package, which is
a test dependency only (``pip install 'sanlab[test]'``); the CLI needs nothing of it.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any

VERSION = 1
RECORDS = ("audit", "ceiling", "check", "creature-entry", "design", "gait", "gait-row", "mjcf-import", "modes", "render", "run", "run-entry",
           "search", "selection", "simulate", "tuning")


def schema_id(name: str) -> str:
    """``"sanlab/<name>/<version>"``, the ``schema`` field of record ``name``."""
    if name not in RECORDS:
        raise ValueError(f"no --json record {name!r} (expected one of {', '.join(RECORDS)})")
    return f"sanlab/{name}/{VERSION}"


@cache
def load(name: str) -> dict:
    """The JSON Schema of record ``name`` (a dict)."""
    schema_id(name)
    return json.loads(resources.files("sanlab").joinpath("schemas", f"{name}.json").read_text(encoding="utf-8"))


def validate(obj: Any, name: str) -> None:
    """Raise ``jsonschema.ValidationError`` unless ``obj`` is a valid record ``name`` (its
    ``$ref`` to another record, e.g. ``gait-row.json``, resolved among these files)."""
    import jsonschema
    from referencing import Registry, Resource

    registry = Registry().with_resources((load(n)["$id"], Resource.from_contents(load(n))) for n in RECORDS)
    schema = load(name)
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.Draft202012Validator(schema, registry=registry, format_checker=jsonschema.FormatChecker()).validate(obj)


__all__ = ["RECORDS", "VERSION", "load", "schema_id", "validate"]
