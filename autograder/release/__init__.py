"""Release tooling: exercises from solutions, the student tree, the Gradescope zip, platforms."""
