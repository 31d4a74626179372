"""``python -m autograder merge PART... --out DIR``: join the outputs of ``batch --shard``.

Each PART is the ``--out`` folder of one shard. Their records (``results/``) and staged
submissions (``submissions/``) are copied into ``DIR``; a student graded in two parts is an
error naming both, unless the two records are the same. The overrides each part keeps
(``overrides.csv``) are joined into ``DIR/overrides.csv`` (a later part's line replacing an earlier
one of the same student and check), so that a ``batch`` run into ``DIR`` applies them. Then
``grades.csv``, ``feedback/`` and ``report.html`` are written for the whole class, as ``batch`` does.
"""

import argparse
import filecmp
import shutil
from pathlib import Path

from autograder.classroom import gradebook, overrides, student_feedback


def merge(parts, out: Path) -> int:
    """Copy the parts' records and submissions into ``out``; returns the number of records."""
    out = Path(out)
    (out / "results").mkdir(parents=True, exist_ok=True)
    origin: dict = {}
    kept = overrides.read(overrides.stored(out))
    for part in map(Path, parts):
        if overrides.stored(part).resolve() != overrides.stored(out).resolve():
            kept = overrides.merge(kept, overrides.read(overrides.stored(part)))[0]
        if not (part / "results").is_dir():
            raise ValueError(f"{part}: no results/ folder (not the --out of `python -m autograder batch`)")
        for path in sorted((part / "results").glob("*.json")):
            sub_id = gradebook.load(path)["extra_data"]["id"]
            target = out / "results" / path.name
            if sub_id in origin and not filecmp.cmp(origin[sub_id], path, shallow=False):
                raise ValueError(f"{sub_id} is graded in both {origin[sub_id]} and {path}, differently")
            origin[sub_id] = path
            if path.resolve() != target.resolve():
                shutil.copyfile(path, target)
                table = path.with_suffix(".txt")
                if table.is_file():
                    shutil.copyfile(table, target.with_suffix(".txt"))
            staged = part / "submissions" / sub_id
            if staged.is_dir() and staged.resolve() != (out / "submissions" / sub_id).resolve():
                shutil.copytree(staged, out / "submissions" / sub_id, dirs_exist_ok=True)
    if kept:
        overrides.write(overrides.stored(out), kept)
    return len(origin)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m autograder merge", description=__doc__.splitlines()[0])
    p.add_argument("parts", nargs="+", help="the --out folders of the shards")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--no-report", action="store_true", help="do not write report.html")
    args = p.parse_args(argv)
    try:
        count = merge(args.parts, Path(args.out))
    except ValueError as exc:
        p.error(str(exc))
    gradebook.write_table(Path(args.out))
    student_feedback.write(Path(args.out))
    if not args.no_report:
        from autograder.classroom import report

        report.write_for_this_tree(Path(args.out))
    print(f"merged {count} records into {Path(args.out) / 'grades.csv'}")
    return 0
