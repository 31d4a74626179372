"""The 2D pose graphs' peers: g2o, Ceres, GTSAM (and GTSAM's LAGO start)."""
