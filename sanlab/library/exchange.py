"""The gait exchange format: one gait as a self-contained JSON object (``sanlab export`` and
``sanlab import``), versioned on its own (:data:`GAIT_FORMAT_VERSION`), independently of the
library's schema.

Fields: ``format`` ("sanlab-gait"), ``version``, ``source`` (the exported ``RUN#IDX``),
``creature``, ``creature_text`` (the creature file, verbatim), ``creature_hash`` (its SHA-256),
``encoding``, ``params``, ``score``, ``speed_cm_s``, ``fell``, ``nonfinite``, ``extra``,
``run_params`` (the source run's settings), ``dtype`` and ``sanlab_version``; ``audit`` (the
gait's artefact audit, when it has one: informative, not imported, since an audit re-simulates the
gait and says what this machine's sanlab makes of it). Strict JSON: NaN and infinities are
written as null. An import refuses any other field (a misspelt optional one would be lost).
"""

from __future__ import annotations

import json
import math
from typing import Any

from sanlab.library._values import sha256, strict_json
from sanlab.library.errors import LibraryError
from sanlab.library.records import Evaluation, Run

GAIT_FORMAT = "sanlab-gait"
GAIT_FORMAT_VERSION = 1


def export_record(run: Run, ev: Evaluation) -> dict:
    """The exchange object of evaluation ``ev`` of ``run``."""
    return strict_json({
        "format": GAIT_FORMAT,
        "version": GAIT_FORMAT_VERSION,
        "source": ev.gait_id,
        "creature": run.creature,
        "creature_text": run.creature_text,
        "creature_hash": run.creature_hash,
        "encoding": ev.encoding,
        "params": ev.params,
        "score": ev.score,
        "speed_cm_s": ev.speed_cm_s,
        "fell": ev.fell,
        "nonfinite": ev.nonfinite,
        "extra": ev.extra,
        "run_params": run.params,
        "dtype": run.dtype,
        "sanlab_version": run.sanlab_version,
    })


def validate_gait(data: Any) -> dict:
    """``data`` if it is a well-formed exported gait; a LibraryError naming the first fault."""
    if not isinstance(data, dict):
        raise LibraryError(f"not a sanlab gait: expected a JSON object, got {type(data).__name__}")
    if "format" not in data or data["format"] is None:
        raise LibraryError(f"not a sanlab gait: it has no \"format\" field (an exported gait has \"format\": "
                           f"\"{GAIT_FORMAT}\"; write one with `sanlab export`)")
    if data.get("format") != GAIT_FORMAT:
        shown = repr(data["format"]) if isinstance(data["format"], str) else json.dumps(data["format"])
        raise LibraryError(f"not a sanlab gait: \"format\" is {shown[:60]}, expected {GAIT_FORMAT!r}")
    version = data.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise LibraryError(f"bad sanlab gait: 'version' must be a positive integer, "
                           f"not {str(version)[:40]}")
    if version > GAIT_FORMAT_VERSION:
        raise LibraryError(f"sanlab gait format version {version} is newer than this sanlab "
                           f"reads ({GAIT_FORMAT_VERSION})")
    number = (int, float)
    fields = {  # name: (accepted types, required)
        "creature": (str, True), "creature_text": (str, True), "encoding": (str, True),
        "params": (dict, True), "score": (number + (type(None),), True),
        "speed_cm_s": (number + (type(None),), True), "fell": (bool, True),
        "run_params": (dict, True), "nonfinite": (bool, False),
        "extra": ((dict, type(None)), False), "source": ((str, type(None)), False),
        "creature_hash": (str, False), "dtype": ((str, type(None)), False),
        "sanlab_version": ((str, type(None)), False), "audit": ((dict, type(None)), False),
    }
    unknown = sorted(str(k)[:40] for k in data.keys() - fields.keys() - {"format", "version"})
    if unknown:  # a misspelt optional field would otherwise be dropped without a word
        raise LibraryError(f"bad sanlab gait: unknown field {', '.join(map(repr, unknown[:5]))} (version "
                           f"{GAIT_FORMAT_VERSION} has {', '.join(['format', 'version', *fields])})")
    for name, (types, required) in fields.items():
        if name not in data:
            if required:
                raise LibraryError(f"bad sanlab gait: missing field {name!r}")
            continue
        value = data[name]
        bad_bool = isinstance(value, bool) and types is not bool
        if bad_bool or not isinstance(value, types):
            raise LibraryError(f"bad sanlab gait: field {name!r} has the wrong type "
                               f"({type(value).__name__})")
    if not data["encoding"].strip():
        raise LibraryError("bad sanlab gait: field 'encoding' is empty")
    for name in fields:
        if isinstance(data.get(name), str):
            try:
                data[name].encode("utf-8")
            except UnicodeEncodeError:
                raise LibraryError(f"bad sanlab gait: field {name!r} is not valid Unicode text") from None
    if "creature_hash" in data and data["creature_hash"] != sha256(data["creature_text"]):
        raise LibraryError("bad sanlab gait: 'creature_hash' does not match 'creature_text' "
                           "(was the creature text edited?)")
    check_content(data)
    return data


def check_content(data: dict) -> None:
    """What :func:`validate_gait` checks beyond the fields' types, so that an imported gait is
    one that replays, renders and tunes: the creature text is a valid creature (today's format
    and limits) named as ``creature`` says; the encoding decodes to this creature's network; the
    parameters fit it (``sanlab.gait.check_params``); the run's settings (seconds, metric, seed)
    are ones it can be evaluated with; score and speed are finite or null; dtype is float32,
    float64 or null. Raises LibraryError ("bad sanlab gait: ...") naming the first fault."""
    from sanlab.creature import CreatureError, loads
    from sanlab.creature.spec import MAX_STEPS
    from sanlab.gait import check_params
    from sanlab.metrics import Metric
    from sanlab.san import San

    def bad(what: str) -> LibraryError:
        return LibraryError(f"bad sanlab gait: {what}")

    try:
        spec = loads(data["creature_text"], "creature_text")
    except CreatureError as e:
        raise bad(str(e)) from None
    if data["creature"] != spec.name:
        raise bad(f"'creature' is {data['creature'][:64]!r} but its creature_text names {spec.name!r}")
    try:
        San.for_creature(spec).decode(data["encoding"])
    except (ValueError, TypeError) as e:  # binascii.Error is a ValueError
        raise bad(f"encoding: {e}") from None
    try:
        check_params(spec, data["params"])
    except ValueError as e:
        raise bad(str(e)) from None
    for name in ("score", "speed_cm_s"):
        v = data[name]
        if v is not None and not math.isfinite(v):
            raise bad(f"{name!r} must be a finite number or null, not {v!r}")
    if data.get("dtype") not in (None, "float32", "float64"):
        raise bad(f"'dtype' must be float32, float64 or null, not {str(data['dtype'])[:40]!r}")
    rp = data["run_params"]
    seconds = rp.get("seconds", spec.evaluation.seconds)
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not 0 < seconds <= MAX_STEPS * spec.dt:
        raise bad(f"run_params.seconds must be a number in (0, {MAX_STEPS * spec.dt:g}] (s), not {str(seconds)[:40]}")
    try:
        Metric.for_creature(spec, rp.get("metric"))
    except (ValueError, TypeError) as e:
        raise bad(f"run_params.metric: {e}") from None
    seed = rp.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63):
        raise bad(f"run_params.seed must be an integer in [0, 2**63 - 1] or null, not {str(seed)[:40]}")
