"""Generated notebooks (``python -m notebooks.build [--execute] [--small]``)."""
