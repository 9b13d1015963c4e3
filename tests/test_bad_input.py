"""Bad input that escaped the one-line errors until a fuzzer found it (issue 33): integers too
large for a float or for Python's int(), names that differ only by spaces around them, and gait
ids with digits of another script. The studio's cases are in ``tests/studio/test_studio_input.py``;
``tests/fuzz.py`` mutates files with the same values."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.creature import CreatureError, loads
from sanlab.library import Library, LibraryError, parse_gait_id
from tests.helpers import BASE, one_line_error

SOURCE = "bad.toml"


def error(text: str) -> str:
    with pytest.raises(CreatureError) as e:
        loads(text, SOURCE)
    message = str(e.value)
    assert one_line_error(message, SOURCE), message
    return message


@pytest.mark.parametrize("old, new, expected", [
    ("mass = 0.1", "mass = 1" + "0" * 309,
     "links[0].mass: expected a positive number of magnitude at most 1e+06 (kg), got an integer of 310 digits"),
    ("mass = 0.1", "mass = -1" + "0" * 309, "links[0].mass: expected a positive number (kg), got an integer of 310 digits"),
    ("points = [[0, 0], [0.2, 0]]", "points = [[0, 0], [" + "4" * 400 + ", 0]]",
     "links[0].points[1]: expected a pair of numbers [x, y] of magnitude at most 1000 (m), got [444"),
    ("mass = 0.1", "mass = 0x" + "f" * 4000,  # hexadecimal: read whatever its length, ~4800 decimal digits
     "links[0].mass: expected a positive number of magnitude at most 1e+06 (kg), got an integer of about 4817 digits"),
    ("min_deg = -90", "min_deg = -" + "9" * 2000,
     "sensors[1].min_deg: expected a number in [-180, 180] (deg), got an integer of 2000 digits"),
    ("contact = 0", "contact = " + "7" * 500, "sensors[0].contact: expected an integer >= 0, got an integer of 500 digits"),
])  # fmt: skip
def test_integers_too_large_for_a_float_get_the_one_line_error(old, new, expected):
    assert old in BASE
    assert expected in error(BASE.replace(old, new, 1))


def test_an_integer_too_long_for_python_to_read_is_located():
    text = BASE.replace("mass = 0.1", "mass = " + "1" * 5000, 1)
    line = text[: text.index("1" * 5000)].count("\n") + 1
    assert error(text) == f"{SOURCE}: line {line}: expected valid TOML, got an integer of more than 4300 digits"
    assert "line 1: expected valid TOML" in error("x = " + "1_2" * 3000 + "\n" + BASE)  # underscores do not count


@pytest.mark.parametrize("name, i", [(" L2", 1), ("L2 ", 1), ("\tL2", 1), (" L1 ", 0)])
def test_a_name_with_spaces_around_it_is_refused(name, i):
    """Refused, not stripped: "L2" and " L2" would be two links that print alike."""
    msg = error(BASE.replace(f'name = "{name.strip()}"', f'name = "{name}"', 1))
    assert f"links[{i}].name: expected a name (printable, not blank, no spaces around it, at most 64 characters)" in msg


def test_names_that_differ_only_by_spaces_are_not_two_links():
    text = BASE.replace('name = "L2"', 'name = " L1"', 1)
    assert "links[1].name: expected a name (printable, not blank, no spaces around it" in error(text)
    sensor = BASE.replace('type = "angle"\nlink = "L2"', 'type = "angle"\nlink = " L2"', 1)
    assert "sensors[1].link: expected one of the link names ['L1', 'L2'] (did you mean 'L2'?), got ' L2'" in error(sensor)
    named = BASE.replace('[[sensors]]\ntype = "touch"', '[[sensors]]\nname = "foot "\ntype = "touch"', 1)
    assert "sensors[0].name: expected a name" in error(named)


@pytest.mark.parametrize("gait", ["3fa1c2d0/\u0661", "3fa1c2d0#\u0661\u0662", "3fa1c2d0/\uff11", "3fa1c2d0/1\u0663",
                                  "\u0663fa1c2d0/1"])
def test_a_gait_id_with_digits_of_another_script_is_malformed(gait):
    with pytest.raises(LibraryError) as e:
        parse_gait_id(gait)
    assert str(e.value).startswith("malformed gait id")


def test_a_rank_or_index_too_long_is_malformed_not_a_crash():
    assert parse_gait_id("3fa1c2d0/1") == ("3fa1c2d0", 1, None)
    assert parse_gait_id("3fa1c2d0#" + "9" * 30) == ("3fa1c2d0", None, 10**30 - 1)  # not found later, like any other
    for gait, what in (("3fa1c2d0/" + "1" * 5000, "a rank"), ("3fa1c2d0#" + "9" * 31, "an index")):
        with pytest.raises(LibraryError) as e:
            parse_gait_id(gait)
        assert f"expected {what} of at most 30 digits" in str(e.value) and len(str(e.value)) < 200


def test_show_refuses_a_non_ascii_rank_in_one_line(tmp_path):
    db = str(tmp_path / "gaits.db")
    with Library(db):
        pass
    r = CliRunner().invoke(app, ["show", "3fa1c2d0/\u0661", "--db", db])
    assert r.exit_code == 2, r.output
    assert r.stderr.count("\n") == 1 and "malformed gait id" in r.stderr, r.stderr
