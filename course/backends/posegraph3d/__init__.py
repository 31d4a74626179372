"""Chapter 6 peers: 3D pose graphs through g2o and GTSAM."""
