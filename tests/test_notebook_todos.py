"""``make notebooks`` (``python -m notebooks.build --execute``) where some exercises are not written: a
failing cell does not stop the build, a TODO is one short output naming it (and so is every later cell
that needs what it did not compute), one line per notebook, exit 0 when the only failures are TODOs."""

import nbformat
import pytest

from notebooks import build

TODO_SOURCE = '''# %% id="a"
x = 1

# %% id="b"
raise NotImplementedError("TODO dogleg.cauchy_point: not implemented yet")
y = 2

# %% id="c"
print(y)

# %% id="d"
print(x + 1)
'''

ERROR_SOURCE = '''# %% id="a"
1 / 0

# %% id="b"
print("after")
'''


def _notebooks(tmp_path, monkeypatch, **sources):
    notebooks = {}
    for name, text in sources.items():
        source = tmp_path / f"{name}.py"
        source.write_text(text)
        notebooks[tmp_path / f"{name}.ipynb"] = source
    monkeypatch.setattr(build, "NOTEBOOKS", notebooks)
    out = tmp_path / "out"
    out.mkdir()
    return out


@pytest.mark.slow
def test_a_todo_is_a_short_output_and_the_build_goes_on(tmp_path, monkeypatch, capsys):
    out = _notebooks(tmp_path, monkeypatch, demo_todo=TODO_SOURCE)
    assert build.main(["--execute", "--out", str(out)]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "WARNING" not in line]
    assert err[0] == (f"wrote {out / 'demo_todo.ipynb'}: 2 of 4 code cells ran in " + err[0].split(" ran in ")[1])
    assert err[0].endswith("; 1 cell(s) stopped at a TODO (dogleg.cauchy_point); 1 after them need their results")
    assert err[1].startswith("not written yet: dogleg.cauchy_point")
    cells = {c.id: c for c in nbformat.read(out / "demo_todo.ipynb", as_version=4).cells}
    (todo,) = cells["b"].outputs
    assert todo["traceback"] == ["not written yet: TODO dogleg.cauchy_point (your dogleg.py; "
                                 "`python -m autograder --only dogleg` grades it)"]
    (after,) = cells["c"].outputs
    assert after["traceback"][0].startswith("not run: this cell needs what a cell above did not compute "
                                            "(TODO dogleg.cauchy_point) [NameError")
    assert cells["d"].outputs[0]["text"] == "2\n"


@pytest.mark.slow
def test_another_error_fails_the_build_but_every_notebook_is_written(tmp_path, monkeypatch, capsys):
    out = _notebooks(tmp_path, monkeypatch, a_error=ERROR_SOURCE, b_todo=TODO_SOURCE)
    assert build.main(["--execute", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "1 failed (first: cell a: ZeroDivisionError: division by zero)" in err
    assert "failed: a cell of a_error.ipynb raised an error other than a TODO" in err
    assert (out / "a_error.ipynb").is_file() and (out / "b_todo.ipynb").is_file()
    cells = {c.id: c for c in nbformat.read(out / "a_error.ipynb", as_version=4).cells}
    assert cells["b"].outputs[0]["text"] == "after\n"
    assert len(cells["a"].outputs[0]["traceback"]) > 1  # not a TODO: the whole traceback


def test_failures_of_a_notebook_without_errors():
    from nbformat.v4 import new_code_cell, new_notebook

    nb = new_notebook(cells=[new_code_cell("x = 1")])
    assert build.failures(nb) == {"todo": [], "after_todo": [], "error": []}
    assert build.outcome("n", nb, 2.0) == "n: all 1 code cells ran in 2 s"
