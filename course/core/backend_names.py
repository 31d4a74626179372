"""The names of the back ends a run may come from, in table order (cheap to import: the command
line lists them)."""

#: our back end's name in every table
OURS = "ours"
#: our minimizer on the problem as a factor graph (chapter 7), its Jacobians by Jets, by central
#: differences or by JAX (``jax.jacfwd`` under ``vmap`` and ``jit`` on the residuals transcribed in
#: ``jax.numpy``): offered where a problem has a factor graph, run when named (``--backends``)
OURS_AUTODIFF, OURS_NUMERIC, JAX = "ours-autodiff", "ours-numeric", "jax"
FACTOR_GRAPH_BACKENDS = {OURS_AUTODIFF: "autodiff", OURS_NUMERIC: "numeric", JAX: "jax"}
#: the same factor graph solved by GTSAM's optimizer, each factor a ``gtsam.CustomFactor`` whose error is
#: our residual and whose Jacobians come from our Jets, one Python callback per factor (offered and run
#: as the factor-graph back ends are)
GTSAM_CUSTOM = "gtsam-custom"
#: every back end a run may come from, in table order
BACKENDS = (OURS, OURS_AUTODIFF, OURS_NUMERIC, JAX, "ceres", "g2o", "gtsam", GTSAM_CUSTOM, "scipy")
