"""Bundle adjustment's peers: Ceres through pycolmap, GTSAM, scipy."""
