"""Chapters 2-3b, 2D pose graphs: the graph, TORO/g2o files, the problem, the trajectory error."""
