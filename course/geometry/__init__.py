"""SE(2) and SO(3), for the framework and given to the exercises that need them."""
