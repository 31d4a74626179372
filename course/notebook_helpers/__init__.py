"""The notebooks' tables and figures, per chapter."""
