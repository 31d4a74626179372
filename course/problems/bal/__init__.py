"""Chapter 4, bundle adjustment: BAL files and the generator, the problem, the gauge, outliers."""
