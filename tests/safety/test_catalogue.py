"""The catalogue of issue 36 (:mod:`tests.safety.catalogue`): every case is refused in one clear
line naming the file / field / name, or flagged, and nothing outside the case's output changes."""

from __future__ import annotations

import pytest

from tests.safety.catalogue import cases, classify

CASES = cases()


def test_the_catalogue_has_at_least_150_cases_over_every_category():
    assert len(CASES) >= 150
    assert {c.category for c in CASES} >= {"calibration", "sequence folder", "detections", "several people",
                                           "security", "detect", "import", "folders", "kills", "concurrency",
                                           "disk full", "read-only"}


@pytest.mark.parametrize("case", CASES, ids=[f"{c.category}: {c.name}" for c in CASES])
def test_bad_input_or_fault_is_refused_clearly_or_flagged(case, tmp_path):
    outcome, line = classify(case, tmp_path / "case")
    if outcome == "n/a":
        pytest.skip(line)
    assert outcome == case.expect, line
