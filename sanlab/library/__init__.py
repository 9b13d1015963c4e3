"""The gait library: every run and every evaluated controller, in one SQLite file.

    with Library("sanlab.db") as lib:
        run = lib.get_run("3fa1c2d0")           # a run, by id or unambiguous prefix
        best = lib.gait("3fa1c2d0/1")           # its best evaluation (RUN/RANK or RUN#IDX)

Modules: ``store`` (:class:`Library`, with its durability and concurrency contract), ``records``
(the frozen :class:`Run`, :class:`Evaluation`, :class:`TracePoint`, :class:`DesignRecord` and
:class:`DesignScore` it returns, the rows it stores and the typed run settings), ``ids`` (the
gait-id grammar), ``exchange`` (the export/import format), ``errors`` (:class:`LibraryError` and
how SQLite's errors map onto it), ``_schema`` (tables, header fields, migrations) and
``_values`` (column value checks).
"""

from sanlab.library._schema import APPLICATION_ID, RUN_KINDS, RUN_STATUSES, SCHEMA_VERSION
from sanlab.library.errors import LibraryError
from sanlab.library.exchange import GAIT_FORMAT, GAIT_FORMAT_VERSION
from sanlab.library.ids import parse_gait_id
from sanlab.library.records import (
    AuditRecord,
    DesignRecord,
    DesignScore,
    Evaluation,
    EvaluationRow,
    Run,
    RunSettings,
    SearchSettings,
    TracePoint,
    TraceRow,
    TuneSettings,
)
from sanlab.library.store import DEFAULT_PATH, Library

__all__ = [
    "APPLICATION_ID", "DEFAULT_PATH", "GAIT_FORMAT", "GAIT_FORMAT_VERSION", "RUN_KINDS",
    "RUN_STATUSES", "SCHEMA_VERSION", "AuditRecord", "DesignRecord", "DesignScore", "Evaluation", "EvaluationRow", "Library", "LibraryError", "Run",
    "RunSettings", "SearchSettings", "TracePoint", "TraceRow", "TuneSettings", "parse_gait_id",
]  # fmt: skip
