"""The course as a static website: ``python -m notebooks.site`` (``make site``).

Sphinx with MyST-NB builds it from what this repository holds at build time:

- ``README.md`` as the index and every ``docs/*.md`` (listed when the site is built);
- each chapter's lesson, ``notebooks/chapterN_*.ipynb``, with its outputs as a student's tree runs
  it (:mod:`notebooks.site.lessons`: a student tree from ``course release``, its ``exercises/``
  written with the reference's files without their hints, ``python -m notebooks.build --execute``
  run there; every execution cached under ``out/site/executed/``);
- a page per chapter (:mod:`notebooks.site.chapter_pages`): its lesson, its exercises with hints
  1 and 2 (never 3) and its assignment from ``autograder/course.toml``.

The site lands in ``out/site/html/`` (``index.html``); the sources Sphinx reads are staged in
``out/site/src/`` (:mod:`notebooks.site.pages`: the pages keep the repository's layout, a link to a
staged page stays a link, a link to any other file of the repository becomes a link to it at
``--source-url``, or plain text without one). The site needs no network: MathJax comes from the
``sphinx-mathjax-offline`` package and is served from ``_static/mathjax/``, and the page loads
nothing from elsewhere (:mod:`notebooks.site.sphinx_config`).

It is the instructor's: a student tree leaves it out, with its guide ``docs/site.md``
(``autograder.release.stubs.INSTRUCTOR_ONLY``).
"""
