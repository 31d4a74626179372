"""The late policy: started days or hours, the cutoff, extensions, and bad policies refused."""

from datetime import datetime, timedelta, timezone

import pytest

from autograder.late import LatePolicy, lateness

DUE = datetime(2026, 10, 1, 23, 59, tzinfo=timezone.utc)


def test_two_days_late_at_ten_percent_a_day_keeps_eighty_percent():
    assert lateness(DUE + timedelta(days=2), DUE, LatePolicy(per_day=0.1)).fraction == pytest.approx(0.8)
    assert lateness(DUE + timedelta(seconds=1), DUE, LatePolicy(per_day=0.1)).fraction == pytest.approx(0.9)
    assert lateness(DUE - timedelta(hours=3), DUE, LatePolicy(per_day=0.1)).fraction == 1.0
    assert lateness(DUE + timedelta(hours=2, minutes=1), DUE, LatePolicy(per_hour=0.05)).fraction == pytest.approx(0.85)
    assert lateness(DUE + timedelta(days=30), DUE, LatePolicy(per_day=0.1)).fraction == 0.0


def test_the_cutoff_and_an_extension():
    policy = LatePolicy(per_day=0.1, cutoff=timedelta(days=3), extensions={"s1@uni.edu": DUE + timedelta(days=5)})
    late = lateness(DUE + timedelta(days=4), DUE, policy)
    assert late.fraction == 0.0 and "cutoff" in late.note
    assert lateness(DUE + timedelta(days=4), DUE, policy, ("17", "s1@uni.edu")).fraction == 1.0
    naive = datetime(2026, 10, 3, 23, 59)  # read as UTC
    assert lateness(naive, DUE, LatePolicy(per_day=0.25)).fraction == pytest.approx(0.5)


@pytest.mark.parametrize("kwargs", [{"per_day": -0.1}, {"per_day": 1.5}, {"per_day": 0.1, "per_hour": 0.1},
                                    {"cutoff": timedelta(days=-1)}])
def test_a_bad_policy_is_refused(kwargs):
    with pytest.raises(ValueError):
        LatePolicy(**kwargs)
