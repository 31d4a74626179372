"""Chapter 5, visual-inertial odometry: the simulator, the problem, the sliding window, APE."""
