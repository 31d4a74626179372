"""The names of our sparse solves of ``H dx = -b`` (``compare --solver``), cheap to import: the
command line lists them; ``course.solver.choice`` makes them."""

#: ``auto`` takes CHOLMOD at or above this many unknowns (n of H): below it the two take about the
#: same time (intel, n = 2187) and the implementation's solver stays the one that runs
AUTO_MIN_UNKNOWNS = 5000
#: what each name runs
SOLVES = {
    "auto": f"CHOLMOD (supernodal) from {AUTO_MIN_UNKNOWNS} unknowns where cvxopt is installed, "
            "else the implementation's",
    "ours": "the implementation's sparse_solve.SparseCholeskySolver (chapter 2; SuperLU without qdldl)",
    "cholmod": "CHOLMOD's supernodal Cholesky through cvxopt (the implementation's where cvxopt is missing)",
    "superlu": "scipy's SuperLU on the whole symmetric H",
}
