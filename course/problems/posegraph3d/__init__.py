"""Chapter 6: 3D pose graphs (SE(3))."""
