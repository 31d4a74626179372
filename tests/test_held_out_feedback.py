"""The feedback on mistakes nobody foresaw: every catalogued mistake judged with its catalogue
stripped still points at the right function and, where the exercise has factors or blocks, the
right one (issue: feedback that locates the mistake)."""

import pytest
from conftest import needs

from student_variants import HOSTILE, VARIANTS
from student_variants.held_out import LOCATES, catalogued, judge_without_catalogue

#: the share of catalogued mistakes whose feedback, without the catalogue, still locates them
LEAST = 0.8


@pytest.fixture(scope="module")
def held_out(tmp_path_factory):
    from autograder import expected
    from autograder.checks import module_of

    modules = module_of()
    names = [name for name, variant in VARIANTS.items() if name not in HOSTILE and variant.fails]
    shipped: dict = {}
    by_check = {}
    for name in names:
        for check in VARIANTS[name].fails:
            shipped.setdefault(modules[check], expected.load(modules[check]))
            by_check[check] = shipped[modules[check]][check]
    return judge_without_catalogue(catalogued(names, by_check), tmp_path_factory.mktemp("held-out"))


@pytest.mark.slow
@needs("pyceres", "qdldl")
def test_the_feedback_still_locates_most_mistakes_without_their_catalogue_entry(held_out):
    missed = [one for one in held_out if not one.ok]
    share = 1 - len(missed) / len(held_out)
    located = [one for one in held_out if one.locates is not None]
    print(f"{len(held_out)} catalogued mistakes judged without the catalogue: {100 * share:.1f}% still name the "
          f"function they are in and, for the {len(located)} in an exercise with factors or blocks, the right one "
          f"({sum(bool(one.locates) for one in located)} do)")
    for one in missed:
        print(f"  {one.name} ({one.function}): lost {one.lost}, names the function: {one.names_function}, "
              f"the factor or block: {one.locates}")
    assert len(held_out) >= 100
    assert share >= LEAST


@pytest.mark.slow
@needs("pyceres", "qdldl")
def test_each_catalogued_mistake_still_costs_its_checks_without_the_catalogue(held_out):
    for one in held_out:
        assert set(one.lost) == set(VARIANTS[one.name].fails), one.name


def test_every_located_variant_exists_and_is_catalogued_somewhere():
    assert set(LOCATES) <= set(VARIANTS)
    assert all(VARIANTS[name].says for name in LOCATES)
