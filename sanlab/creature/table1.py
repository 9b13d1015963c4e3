"""Table 1 of van de Panne & Fiume (1993): the creatures the built-ins reproduce.

Each built-in creature named here has the table's counts of links, sensors, actuators and hidden
nodes (the tests check it); ``sanlab reproduce`` compares its speeds with the table's.
"""

from __future__ import annotations

from typing import NamedTuple


class Table1Row(NamedTuple):
    links: int
    sensors: int
    actuators: int
    hidden: int
    speed_cm_s: float | None  # the paper's speed; None where Table 1 says "U" (unmeasured)


TABLE1: dict[str, Table1Row] = {
    "crawler": Table1Row(4, 8, 2, 10, None),
    "fish": Table1Row(4, 6, 2, 5, 19.0),
    "bounder": Table1Row(5, 8, 4, 8, 115.0),
    "luxo": Table1Row(3, 6, 2, 6, 79.0),
    "cart": Table1Row(2, 6, 1, 5, 23.0),
    "walker": Table1Row(6, 11, 5, 6, 101.0),
    "twolink": Table1Row(2, 6, 1, 5, 12.0),
    "threelink": Table1Row(3, 8, 2, 7, 33.0),
    "fourlink": Table1Row(4, 11, 3, 8, 55.0),
    "star": Table1Row(3, 8, 2, 7, 9.0),
}
