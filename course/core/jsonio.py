"""JSON (and other text) files written whole or not at all (standard library only: the
Gradescope ``finish`` step uses it when grading could not start)."""

import json
import os
import uuid
from pathlib import Path


def write_json(path, data, indent=None, *, newline: bool = False) -> Path:
    """Write ``data`` as ``json.dumps(data, indent=indent)`` to ``path``, plus ``"\\n"`` when
    ``newline``; returns the path.

    The folders are made; the text goes to a temporary file in the same folder, then
    ``os.replace`` puts it at ``path``, so a reader sees the old file or the new one, never a
    part. ``data`` that is not JSON-serialisable raises before anything is written.
    """
    return write_text(path, json.dumps(data, indent=indent) + ("\n" if newline else ""))


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all, as :func:`write_json` does."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # a name of our own rather than tempfile.mkstemp, whose file is 0600: this one gets the
    # permissions (umask) any other new file would
    temporary = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        with open(temporary, "x", encoding="utf-8") as file:
            file.write(text)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)
    return path
