"""autograder.feedback: when only some rows of an output go wrong, the feedback says which and of what kind."""

import numpy as np

from autograder.expected import Expected, decode_expected, encode_expected
from autograder.feedback import compare, which_rows
from autograder.records import Call, Outcome

GROUPS = {"whose rotation is near pi": (7,), "seen by camera 0": (0, 1, 2), "written backwards": (2, 5)}


def test_rows_that_go_wrong_are_named_with_their_kind():
    bad = np.zeros((11, 3), dtype=bool)
    bad[7, 1] = True
    assert which_rows(bad, GROUPS) == "; only row 7 of 11 goes wrong: exactly the one whose rotation is near pi"
    bad[7] = False
    bad[[0, 2], 0] = True
    assert which_rows(bad, GROUPS) == "; only rows 0, 2 of 11 go wrong, all of them among those seen by camera 0"
    bad[5, 2] = True
    assert which_rows(bad, GROUPS) == ("; only rows 0, 2, 5 of 11 go wrong (2 of the 3 rows seen by camera 0; "
                                       "2 of the 2 rows written backwards)")


def test_nothing_is_said_when_every_row_or_a_single_row_output_goes_wrong():
    assert which_rows(np.ones((4, 2), dtype=bool), GROUPS) == ""
    assert which_rows(np.ones(1, dtype=bool), GROUPS) == ""
    assert which_rows(np.array(True), GROUPS) == ""


def test_compare_says_it_for_wrong_and_for_non_finite_rows():
    expected = np.arange(33.0).reshape(11, 3)
    wrong = expected.copy()
    wrong[7, 0] += 1.0
    assert "exactly the one whose rotation is near pi" in compare(wrong, expected, "e", 1e-9, 1e-12, groups=GROUPS)
    wrong[7, 0] = np.nan
    text = compare(wrong, expected, "e", 1e-9, 1e-12, groups=GROUPS)
    assert "not a finite number" in text and "exactly the one whose rotation is near pi" in text
    assert compare(wrong, expected, "e", 1e-9, 1e-12).endswith("; only row 7 of 11 goes wrong")  # no kinds



def test_a_non_finite_entry_keeps_the_cause_and_the_known_slip():
    """A Jet's sqrt whose derivative at 0 is +inf where the contract wants -inf (the derivative's sign):
    the line says which entry is not a number and, as for any other wrong entry, the likely cause, or
    the known slip whose output has the same infinity or nan there."""
    expected = np.array([[-np.inf, 0.5], [0.0, 1.0]])
    got = np.array([[np.inf, 0.5], [0.0, 1.0]])
    cause = "d sqrt(x) = dx / (2 sqrt(x)); at 0 see the docstring"
    text = compare(got, expected, "grad", 1e-12, 1e-14, "at x = 0", (), cause)
    assert text == (f"grad[0, 0] = inf (not a finite number), expected -inf at x = 0; only row 0 of 2 goes wrong: "
                    f"{cause}")
    slip = (np.array([[np.inf, 0.5], [0.0, 1.0]]), "the infinity takes the derivative's sign")
    other = (np.array([[np.nan, 0.5], [0.0, 1.0]]), "a nan")
    assert compare(got, expected, "grad", 1e-12, 1e-14, "at x = 0", (other, slip), cause).endswith(
        ": the infinity takes the derivative's sign")
    got[0, 0] = np.nan
    assert compare(got, expected, "grad", 1e-12, 1e-14, "", (slip, other), cause).endswith(": a nan")

def test_groups_travel_with_the_shipped_data():
    call = Call("m:f", (np.ones(2),), groups={"seen by camera 0": (0, 1)})
    data = decode_expected(encode_expected(Expected([call], [Outcome(fields={"value": np.ones(2)})], [{}])))
    assert data.calls[0].groups == {"seen by camera 0": (0, 1)}
