#!/usr/bin/env bash
# Gradescope runs this once, as root, when it builds the autograder image (Ubuntu 22.04,
# CPython 3.10), from /autograder/source. It installs what grading imports (pinned in
# requirements.txt, each a CPython 3.10 wheel); no apt-get is needed.
set -euo pipefail
SOURCE="$(cd "$(dirname "$0")" && pwd)"   # /autograder/source
umask 022   # the student's code runs as an unprivileged user, who must be able to import these
python3 -m pip install --only-binary=:all: -r "$SOURCE/requirements.txt"
python3 -c "import numpy, scipy, qdldl, pyceres, threadpoolctl; print('grading imports ok: numpy', numpy.__version__, 'scipy', scipy.__version__)"
