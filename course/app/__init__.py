"""The application: the command line, compare, the benchmarks, plots, the VIO comparison."""
