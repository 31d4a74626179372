"""The submissions of a class: a folder of submission folders, or Gradescope's export.

* **A folder**: every subfolder (not hidden) is one student's upload, in any layout a
  single upload may have (:func:`autograder.submission.locate_submission` finds the
  exercise files in it); the folder's name is the student's id and name.
* **Gradescope's "Export Submissions" zip**: one ``submission_<number>/`` folder per
  submission and ``submission_metadata.yml`` mapping each folder to its submitters
  (``:submitters:`` with ``:name:``, ``:sid:``, ``:email:``). The zip is unpacked into a
  folder of the output (members checked: no absolute paths, no ``..``, no links, bounded
  sizes). A group submission is one row, its submitters' names joined with "; ".

The submission's time: the export's ``:created_at:`` (Gradescope's time of that submission), or
for a folder of uploads the modification time of the newest file in the student's folder (what
the upload kept: copy with ``cp -p``, ``rsync -t`` or unzip to keep it). A roster the instructor
gives (:mod:`autograder.classroom.roster`) overrides either.

Ids are made safe as file names (letters, digits, ``-``, ``_``, ``.``); two submissions
with the same safe id are an error naming both.
"""

import os
import re
import shutil
import stat
import zipfile
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

METADATA = "submission_metadata.yml"
#: caps on an export zip: members and bytes unpacked
MAX_MEMBERS = 200_000
MAX_BYTES = 8 * 2**30
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


class IntakeError(ValueError):
    """The submissions cannot be read; the message names the file and what is wrong."""


@dataclass(frozen=True)
class Submission:
    id: str
    name: str
    path: Path  # the upload's folder
    sid: str = ""
    email: str = ""
    submitted: datetime | None = None  # when it was handed in, with a time zone
    submitted_from: str = ""  # "export metadata", "file time" or "roster"


_TIME = re.compile(r"(\d{4}-\d\d-\d\d)[T ](\d\d:\d\d(?::\d\d)?)(?:\.(\d+))?\s*(Z|[+-]\d\d:?\d\d)?$")


def parse_time(value) -> datetime:
    """A time as the export, a roster or the command line writes it: a datetime (PyYAML reads the
    export's ``:created_at:`` as one), ISO 8601, or ``2026-11-20 10:00:00.000000000 -08:00``; one
    without a time zone is UTC. ``ValueError`` naming the text otherwise."""
    if isinstance(value, datetime):
        moment = value
    else:
        text = str(value).strip()
        m = _TIME.match(text)
        if not m:
            try:
                moment = datetime.fromisoformat(text)
            except ValueError:
                raise ValueError(f"{text!r} is not a time (expected e.g. 2026-10-01T23:59:00+02:00)") from None
        else:
            day, clock, fraction, zone = m.groups()
            zone = "" if zone is None else ("+00:00" if zone == "Z" else zone[:3] + ":" + zone[-2:])
            fraction = "." + (fraction + "000000")[:6] if fraction else ""
            moment = datetime.fromisoformat(f"{day}T{clock}{fraction}{zone}")
    return moment if moment.tzinfo is not None else moment.replace(tzinfo=timezone.utc)


def newest_file_time(folder: Path) -> datetime | None:
    """The modification time of the newest regular file under ``folder`` (links not followed)."""
    newest = None
    for directory, dirs, names in os.walk(folder):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d != "__pycache__"]
        for name in names:
            try:
                info = os.lstat(os.path.join(directory, name))
            except OSError:
                continue
            if stat.S_ISREG(info.st_mode) and (newest is None or info.st_mtime > newest):
                newest = info.st_mtime
    return None if newest is None else datetime.fromtimestamp(newest, tz=timezone.utc)


def safe_id(text: str) -> str:
    """``text`` as a file name: runs of other characters become ``_``."""
    cleaned = _UNSAFE.sub("_", str(text)).strip("._")
    return cleaned or "_"


def read(source, unpack_to=None) -> list:
    """The submissions in ``source`` (a folder, or an export zip unpacked under
    ``unpack_to``), sorted by id."""
    source = Path(source)
    if source.is_file() and zipfile.is_zipfile(source):
        if unpack_to is None:
            raise IntakeError(f"{source}: a zip needs a folder to be unpacked into")
        return from_export(unpack(source, Path(unpack_to)))
    if not source.is_dir():
        raise IntakeError(f"{source}: neither a folder of submissions nor a zip file")
    children = [source / name for name in _names(source) if (source / name).is_dir()]
    if (source / METADATA).is_file() or (len(children) == 1 and (children[0] / METADATA).is_file()):
        return from_export(source)  # an export unpacked by hand
    return from_folder(source)


def _names(folder: Path) -> list:
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))


def from_folder(folder: Path) -> list:
    """One submission per subfolder of ``folder``, named after it."""
    subs = []
    for name in _names(folder):
        if (folder / name).is_dir():
            when = newest_file_time(folder / name)
            subs.append(Submission(safe_id(name), name, folder / name, submitted=when,
                                   submitted_from="file time" if when else ""))
    if not subs:
        raise IntakeError(f"{folder}: no submission in it (one subfolder per student)")
    return _unique(subs, folder)


def _unique(subs: list, where: Path) -> list:
    seen: dict = {}
    for sub in subs:
        if sub.id in seen:
            raise IntakeError(f"{where}: {seen[sub.id].path.name!r} and {sub.path.name!r} both have the id {sub.id!r}")
        seen[sub.id] = sub
    return sorted(subs, key=lambda sub: sub.id)


def from_export(folder: Path) -> list:
    """The submissions of an unpacked Gradescope export (the folder holding
    ``submission_metadata.yml``, or a folder above it)."""
    found = sorted(folder.rglob(METADATA))
    if not found:
        raise IntakeError(f"{folder}: no {METADATA} (is it Gradescope's 'Export Submissions' zip?)")
    if len(found) > 1:
        raise IntakeError(f"{folder}: {len(found)} files named {METADATA}; expected one")
    metadata_path = found[0]
    root = metadata_path.parent
    try:
        import yaml
    except ImportError:
        raise IntakeError(f"{metadata_path}: reading it needs PyYAML (pip install pyyaml)") from None
    try:
        metadata = yaml.safe_load(metadata_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise IntakeError(f"{metadata_path}: not readable YAML ({exc})") from None
    if not isinstance(metadata, dict):
        raise IntakeError(f"{metadata_path}: expected a mapping of submission folders to their metadata")
    subs = []
    for key, entry in metadata.items():
        folder_name = str(key)
        submitters = _get(entry, "submitters") if isinstance(entry, dict) else None
        if not isinstance(submitters, list) or not all(isinstance(s, dict) for s in submitters):
            raise IntakeError(f"{metadata_path}: {folder_name}: no ':submitters:' list")
        if not (root / folder_name).is_dir():
            raise IntakeError(f"{metadata_path}: {folder_name} is listed, but there is no folder {folder_name}/")

        number = folder_name.removeprefix("submission_")
        created = _get(entry, "created_at")
        try:
            when = parse_time(created) if created not in (None, "") else None
        except ValueError as exc:
            raise IntakeError(f"{metadata_path}: {folder_name}: ':created_at:' {exc}") from None
        subs.append(Submission(safe_id(number), _joined(submitters, "name") or folder_name, root / folder_name,
                               _joined(submitters, "sid"), _joined(submitters, "email"), submitted=when,
                               submitted_from="export metadata" if when else ""))
    if not subs:
        raise IntakeError(f"{metadata_path}: lists no submission")
    return _unique(subs, metadata_path)


def _get(entry: dict, key: str):
    """``entry[":key"]``: the export's keys are Ruby symbols (``:name:`` reads as ``":name"``)."""
    return entry.get(f":{key}", entry.get(key))


def _joined(submitters: list, key: str) -> str:
    """The submitters' ``:key:`` values joined with "; " (a group submission is one row)."""
    return "; ".join(str(_get(s, key)) for s in submitters if _get(s, key))


def unpack(archive_path: Path, target: Path) -> Path:
    """Unpack the zip ``archive_path`` into ``target`` (emptied first); returns ``target``."""
    with zipfile.ZipFile(archive_path) as archive:
        members = archive.infolist()
        if len(members) > MAX_MEMBERS:
            raise IntakeError(f"{archive_path}: {len(members)} members, more than {MAX_MEMBERS}")
        if sum(m.file_size for m in members) > MAX_BYTES:
            raise IntakeError(f"{archive_path}: unpacks to more than {MAX_BYTES // 2**30} GiB")
        if target.exists():
            shutil.rmtree(target)
        target.mkdir(parents=True)
        for member in members:
            parts = Path(member.filename).parts
            kind = stat.S_IFMT(member.external_attr >> 16)
            if member.filename.startswith(("/", "\\")) or ".." in parts or (kind and kind not in (stat.S_IFREG,
                                                                                                  stat.S_IFDIR)):
                continue  # an absolute path, a way out, or a link: never extracted
            archive.extract(member, target)
    return target
