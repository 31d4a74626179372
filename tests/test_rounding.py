"""The data and the grades do not turn on rounding: the public data rendered from inputs moved by a
few units in the last place, or with other LAPACK drivers, is the shipped data; the reference's answer
on moved inputs, or computed with other drivers, keeps full marks on every public and hidden input
(an input whose answer is not unique passes only where its judge compares by properties); the oracle
keeps a known mistake only where rounding does not move it."""

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from autograder import expected, oracle
from autograder.checks import modules
from autograder.grade import missing_library
from autograder.records import Context
from autograder.rounding import close, moved, moved_call, short, stable

SALTS = (1, 2)


def moved_check(check, salt):
    """``check`` whose calls have their inputs moved (as they are where ``exact_inputs``)."""
    if check.exact_inputs:
        return check
    return dataclasses.replace(check, calls=lambda seed=None: [moved_call(c, salt=salt) for c in check.calls(seed)])


def stale_modules(salt=None) -> list:
    """The check modules whose public data, rendered now (from moved inputs with ``salt``), is not the
    shipped data."""
    stale = []
    for name, module in modules():
        checks = [c if salt is None else moved_check(c, salt) for c in module.CHECKS]
        if missing := [c.name for c in checks if missing_library(c)]:
            pytest.skip(f"{missing[0]} needs a library not installed here")
        public = {c.name: oracle.compute(c, name) for c in checks}
        if not expected.same_data(expected.path_for(name).read_text(), expected.dumps(public)):
            stale.append(name)
    return stale


#: the expected data of each check (public and hidden inputs), computed once for the three tests that
#: judge against it, always with numpy's own drivers
_EXPECTED: dict = {}


def _expected(check, name, seed):
    if (check.name, seed) not in _EXPECTED:
        _EXPECTED[check.name, seed] = oracle.compute(check, name, seed)
    return _EXPECTED[check.name, seed]


def short_of_full_marks(answer) -> list:
    """``(check, set, feedback)`` of every check where ``answer(check, module, seed)`` (the reference's
    outcomes on the check's inputs, computed some other way) loses points against the expected data."""
    lost = []
    for name, module in modules():
        for check in module.CHECKS:
            if missing_library(check):
                continue
            for seed in (None, oracle.hidden_seed()):
                want = _expected(check, name, seed)
                context = Context(check, want.calls, answer(check, name, seed), want.reference, "", want.mistakes)
                with np.errstate(all="ignore"):
                    verdict = check.judge(context)
                if verdict.fraction < 1.0:
                    lost.append((check.name, "public" if seed is None else "hidden", verdict.message[:300]))
    return lost


@pytest.mark.slow
@pytest.mark.parametrize("salt", SALTS)
def test_the_public_data_rendered_from_moved_inputs_is_the_shipped_data(salt):
    assert stale_modules(salt) == []


@pytest.mark.slow
@pytest.mark.parametrize("salt", SALTS)
def test_the_reference_on_moved_inputs_keeps_full_marks_on_every_input(salt):
    def answer(check, name, seed):
        return oracle.reference_outcomes(moved_check(check, salt).calls(seed))

    assert short_of_full_marks(answer) == []


def _stacked(function):
    """``function`` of one matrix applied to each of a stack ``(..., m, n)``, outputs stacked alike."""

    def apply(a, *args, **kwargs):
        a = np.asarray(a)
        if a.ndim == 2:
            return function(a, *args, **kwargs)
        outs = [apply(m, *args, **kwargs) for m in a.reshape(-1, *a.shape[-2:])]
        if not isinstance(outs[0], tuple):
            return np.stack(outs).reshape(*a.shape[:-2], *outs[0].shape)
        return tuple(np.stack([o[k] for o in outs]).reshape(*a.shape[:-2], *outs[0][k].shape)
                     for k in range(len(outs[0])))

    return apply


def use_other_lapack_drivers(monkeypatch):
    """numpy's SVD by LAPACK's gesvd (numpy: gesdd) and its symmetric eigensolver by syev (numpy:
    syevd), through scipy: another machine's LAPACK, as far as one process can have it. The oracle's
    cache of the test run is off: its numbers are numpy's drivers'."""

    def svd(a, full_matrices=True, compute_uv=True, hermitian=False):
        return scipy.linalg.svd(a, full_matrices=full_matrices, compute_uv=compute_uv, lapack_driver="gesvd")

    def eigh(a, UPLO="L"):
        return scipy.linalg.eigh(a, lower=UPLO == "L", driver="ev")

    monkeypatch.setattr(np.linalg, "svd", _stacked(svd))
    monkeypatch.setattr(np.linalg, "eigh", _stacked(eigh))
    monkeypatch.delenv(oracle.CACHE_VARIABLE, raising=False)
    oracle.forget()


def nearest_rotation(M):
    U, _, Vt = np.linalg.svd(M)
    U[..., :, 2] *= np.linalg.det(np.matmul(U, Vt))[..., None]
    return np.matmul(U, Vt)


def test_the_other_drivers_pick_another_nearest_rotation_where_it_is_not_unique(monkeypatch):
    """What makes the drivers a test: on exact reflections -R they pick other rotations than numpy's
    (here 6 of 50), at the same distance; on a matrix with distinct singular values, the same one."""
    from course.geometry.so3 import exp_many

    M = -exp_many(np.random.default_rng(0).normal(size=(50, 3)))
    general = np.random.default_rng(1).normal(size=(3, 3))
    ours, ours_general = nearest_rotation(M), nearest_rotation(general)
    use_other_lapack_drivers(monkeypatch)
    other, other_general = nearest_rotation(M), nearest_rotation(general)
    assert not np.allclose(ours, other, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(ours - M, axis=(1, 2)), np.linalg.norm(other - M, axis=(1, 2)))
    np.testing.assert_allclose(ours_general, other_general, atol=1e-12)
    oracle.forget()


@pytest.mark.slow
def test_with_other_lapack_drivers_the_data_and_the_grades_are_the_same(monkeypatch):
    use_other_lapack_drivers(monkeypatch)
    assert stale_modules() == []
    answers = {(check.name, seed): oracle.reference_outcomes(check.calls(seed))
               for name, module in modules() for check in module.CHECKS if not missing_library(check)
               for seed in (None, oracle.hidden_seed())}
    monkeypatch.undo()
    oracle.forget()
    assert short_of_full_marks(lambda check, name, seed: answers[(check.name, seed)]) == []


def test_a_move_keeps_zeros_symmetry_repeats_and_short_numbers():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(5, 5))
    H = A + A.T
    H[1, 3] = H[3, 1] = 0.0
    H[0, 0] = 6.25
    M = moved(H, ulps=4, salt=3)
    assert np.array_equal(M, M.T) and M[1, 3] == 0.0 and M[0, 0] == 6.25
    assert not np.array_equal(M, H) and np.all(np.abs(M - H) <= 4 * np.finfo(float).eps * np.abs(H))
    assert moved((H, [H], {"k": H}), salt=3)[1][0].tolist() == M.tolist()
    assert short(np.array([0.0, 1.0, 1 + 2.0**-20, 0.1, np.pi])).tolist() == [True, True, True, False, False]
    assert isinstance(moved(np.array(0.1)), np.ndarray) and moved(np.array(0.1)).shape == ()
    assert moved(3) == 3 and moved("text") == "text"


def test_a_mistake_that_rounding_moves_or_that_is_not_finite_is_dropped():
    here = {"x": [(np.array([1.0, 2.0]), "kept"), (np.array([1.0, 5.0]), "moved"), (np.array([np.nan]), "nan"),
                  (np.array([3.0]), "gone")]}
    there = {"x": [(np.array([1.0, 2.0 + 1e-15]), "kept"), (np.array([1.0, 5.1]), "moved"),
                   (np.array([np.nan]), "nan")]}
    assert [why for _, why in stable(here, there)["x"]] == ["kept"]
    assert close(np.array([1e3, 1e-20]), np.array([1e3, 1e-12])) and not close(np.ones(2), np.ones(3))
