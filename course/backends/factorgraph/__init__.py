"""Chapter 7's factor graphs through the other automatic-differentiation paths: GTSAM's
``CustomFactor`` (Python callbacks whose error is our residual and whose Jacobians are our Jets',
``gtsam_custom``) and JAX (the factor types' own residuals traced by JAX, Jacobians by ``jax.jacfwd``
under ``vmap`` and ``jit``, for our minimizer, ``jax_factors``); and a planar graph of the library's
priors, betweens and ranges in GTSAM's own C++ factors (``gtsam_native``)."""
