"""docs/creature-format.md documents every field the loader accepts, and the old place of the
format (sanlab/creature/FORMAT.md, named in the built-in files' comments and in messages) still
leads to it."""

from __future__ import annotations

import re
from pathlib import Path

from sanlab.creature import _toml, free

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "creature-format.md"


def _fields() -> dict[str, set[str]]:
    tables = {"top level": _toml.TOP, "[world]": _toml.WORLD, "[world.ground]": _toml.GROUND,
              "[world.follow]": _toml.FOLLOW, "[san]": _toml.SAN, "[evaluation]": _toml.EVALUATION,
              "[[links]]": _toml.LINK, "spring": _toml.SPRING, "limit": _toml.LIMIT, "friction": _toml.FRICTION,
              "a point": _toml.POINT, "[[springs]]": _toml.SPRINGS, "a free number": free.FREE,
              "a use of one": free.SAME, "[design]": free.DESIGN, "[[design.total]]": free.TOTAL}
    for kind, keys in _toml.TERRAIN.items():
        tables[f"terrain {kind}"] = keys
    for kind, keys in _toml.SENSOR.items():
        tables[f"sensor {kind}"] = keys | {"name", "type"}
    for kind, keys in _toml.ACTUATOR.items():
        tables[f"actuator {kind}"] = keys | {"name", "type"}
    return tables


def test_every_field_the_loader_accepts_is_on_the_page():
    text = PAGE.read_text(encoding="utf-8")
    # every word inside a code span: `mass`, `[world.ground]`, `{ stiffness = k, rest_deg = 0 }`
    quoted = {word for span in re.findall(r"`([^`\n]+)`", text) for word in re.findall(r"[A-Za-z_]+", span)}
    missing = {table: sorted(keys - quoted) for table, keys in _fields().items() if keys - quoted}
    assert not missing, f"fields without a `name` on docs/creature-format.md: {missing}"


def test_every_sensor_actuator_and_terrain_kind_is_on_the_page():
    text = PAGE.read_text(encoding="utf-8")
    for kind in (*_toml.SENSOR, *_toml.ACTUATOR, *_toml.TERRAIN):
        assert f'`"{kind}"`' in text, kind


def test_the_old_place_points_to_the_page():
    old = ROOT / "sanlab" / "creature" / "FORMAT.md"
    text = old.read_text(encoding="utf-8")
    target = re.search(r"\]\(([^)]*creature-format\.md)\)", text)
    assert target is not None, "sanlab/creature/FORMAT.md must link to docs/creature-format.md"
    assert (old.parent / target.group(1)).resolve() == PAGE.resolve()
    assert len(text) < 1000, "FORMAT.md is a pointer: the format lives in docs/creature-format.md"
