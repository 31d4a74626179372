"""The names of the back ends a run may come from, in table order (cheap to import: the command
line lists them)."""

#: our back end's name in every table
OURS = "ours"
#: every back end a run may come from, in table order
BACKENDS = (OURS, "ceres", "g2o", "gtsam", "scipy")
