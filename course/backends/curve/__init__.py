"""The curve fit's peers: Ceres through pyceres, scipy."""
