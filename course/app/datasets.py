"""The named data of chapters 4 and 5 for ``python -m course datasets`` (the pose graphs list
their own: ``course.problems.posegraph.dataset.list_datasets``)."""

from course.core import chapters
from course.core.errors import DatasetError


def list_other_data() -> list[tuple[str, str, str, str]]:
    """The other chapters' named data: ``(name, size, where, reason missing or "")`` for the BAL
    problems (chapter 4), EuRoC MH_05's trajectories and the VIO simulator (chapter 5), those of the
    chapters this tree holds."""
    rows: list[tuple[str, str, str, str]] = []
    if chapters.handed_out("ch4"):
        from course.problems.bal import dataset as bal

        rows += bal.catalogue()
    if not chapters.handed_out("ch5"):
        return rows
    from course.problems.vio import ape

    try:
        ape.euroc_mh05_files()
        reason = ""
    except DatasetError as e:
        reason = getattr(e, "short", str(e))
    rows.append(("euroc-mh05", "EuRoC CSV truth + a TUM estimate", f"data folder: {', '.join(ape.EUROC_MH05)}",
                 reason))
    rows.append(("vio-sim[:seconds[:seed]]", "IMU 200 Hz, camera 20 Hz, 480 pts", "generator course.problems.vio.sim",
                 ""))
    return rows
