"""The names of the back ends a run may come from, in table order (cheap to import: the command
line lists them)."""

#: our back end's name in every table
OURS = "ours"
#: our minimizer on the problem as a factor graph (chapter 7), its Jacobians by Jets or by central
#: differences: offered where a problem has a factor graph, run when named (``--backends``)
OURS_AUTODIFF, OURS_NUMERIC = "ours-autodiff", "ours-numeric"
FACTOR_GRAPH_BACKENDS = {OURS_AUTODIFF: "autodiff", OURS_NUMERIC: "numeric"}
#: every back end a run may come from, in table order
BACKENDS = (OURS, OURS_AUTODIFF, OURS_NUMERIC, "ceres", "g2o", "gtsam", "scipy")
