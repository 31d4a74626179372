"""Least-squares problems: each gives the loop linearize / chi2 / solve / retract."""
