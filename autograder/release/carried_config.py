"""The course configuration a released tree carries: ``autograder/course.toml`` rewritten.

A student tree is read by every student, so its configuration keeps no personal data: the keys of
:data:`PERSONAL_KEYS` (extensions, by e-mail, id or sid; a roster) are dropped at any depth, and
the tree's students see their own due date in the feedback of the Gradescope run, never the class's.
The Gradescope zip is uploaded by the instructor and never shown to students, and grades with the
extensions: it keeps them (``personal=True``).
"""

import json
import re
import sys
from datetime import date, datetime
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: keys whose values name students; dropped from every student tree's configuration
PERSONAL_KEYS = frozenset({"extensions", "roster", "students"})
HEADER = "# The course configuration of this {what} (autograder/course_config.py says what each key means)."


def _key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, (datetime, date)):
        return value.isoformat()
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {value!r} as TOML")


def without_personal(value):
    """``value`` (the TOML's contents) with every key of :data:`PERSONAL_KEYS` dropped, at any depth."""
    if isinstance(value, dict):
        return {k: without_personal(v) for k, v in value.items() if k not in PERSONAL_KEYS}
    if isinstance(value, list):
        return [without_personal(v) for v in value]
    return value


def has_personal(value) -> bool:
    """True when ``value`` holds a key of :data:`PERSONAL_KEYS` at any depth."""
    if isinstance(value, dict):
        return any(k in PERSONAL_KEYS or has_personal(v) for k, v in value.items())
    if isinstance(value, list):
        return any(has_personal(v) for v in value)
    return False


def _table(name: str, table: dict) -> list:
    return [f"[{name}]"] + [f"{_key(k)} = {_value(v)}" for k, v in table.items()] + [""]


def config_text(source: Path, name: str | None = None, personal: bool = False) -> str:
    """The course configuration of ``source`` as TOML: with assignment ``name`` alone (None: every
    assignment); without the keys of :data:`PERSONAL_KEYS` unless ``personal``."""
    with open(source, "rb") as handle:
        data = tomllib.load(handle)
    if not personal:
        data = without_personal(data)
    out = [HEADER.format(what="assignment" if name else "course"), ""]
    for table in ("course", "defaults"):
        if data.get(table):
            out += _table(table, data[table])
    names = [name] if name else list(data.get("assignments", {}))
    for each in names:
        out += _table(f"assignments.{_key(each)}", data["assignments"][each])
    return "\n".join(out).rstrip("\n") + "\n"
