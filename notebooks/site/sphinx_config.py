"""The Sphinx configuration of the site, written as ``conf.py`` into the staged sources, and the build.

MyST-NB reads the guides (``.md``) and the executed lessons (``.ipynb``) without executing them again
(``nb_execution_mode = "off"``: :mod:`notebooks.site.lessons` ran them in a student tree). Math is
``$...$`` and ``$$...$$`` (MyST's ``dollarmath``, ``amsmath`` for a bare ``\\begin{aligned}``), typeset
in the browser by MathJax 3 from the ``sphinx-mathjax-offline`` package, copied to
``_static/mathjax/``; no widget script is loaded (MyST-NB's default takes require.js and the widget
manager from a CDN). The theme is furo, whose assets ship in its package.
"""

import subprocess
import sys
from pathlib import Path

#: the MathJax extension: its package's folder name has hyphens, and it sets ``mathjax_path``
MATHJAX_OFFLINE = "sphinx-mathjax-offline"


def settings(title: str) -> dict:
    """The values of ``conf.py``."""
    return {
        "project": title,
        "html_title": title,
        "extensions": ["myst_nb", "sphinx.ext.mathjax", MATHJAX_OFFLINE],
        "html_theme": "furo",
        "nb_execution_mode": "off",
        "nb_merge_streams": True,
        "nb_ipywidgets_js": {},
        "myst_enable_extensions": ["dollarmath", "amsmath"],
        "myst_dmath_double_inline": True,
        "myst_heading_anchors": 4,
        "html_copy_source": False,
        "html_show_sourcelink": False,
        "exclude_patterns": ["_build"],
        "suppress_warnings": ["myst.header", "misc.highlighting_failure"],
    }


def conf_text(title: str) -> str:
    """The text of ``conf.py``: :func:`settings`, one line each."""
    lines = ['"""Written by python -m notebooks.site (notebooks/site/sphinx_config.py): edit that file."""', ""]
    lines += [f"{key} = {value!r}" for key, value in settings(title).items()]
    return "\n".join(lines) + "\n"


def run_sphinx(src: Path, html: Path, doctrees: Path, log=print) -> list:
    """``python -m sphinx -b html src html``; returns its warning lines (an error exit raises)."""
    argv = [sys.executable, "-m", "sphinx", "-b", "html", "-q", "--keep-going", "-d", str(doctrees), str(src),
            str(html)]
    done = subprocess.run(argv, capture_output=True, text=True)
    warnings = [line for line in done.stderr.splitlines() if line.strip()]
    if done.returncode != 0:
        raise RuntimeError(f"sphinx-build exited {done.returncode}:\n" + "\n".join(warnings[-30:]))
    return warnings
