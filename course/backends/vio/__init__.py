"""The visual-inertial window's peer: GTSAM's IMU factors and fixed-lag smoother."""
