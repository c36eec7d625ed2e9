"""The hybrid tracker on data our model did not generate (data/mismatch): its misalignment check
fires and its APF runs, and it ends no worse than the local tracker alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import mocap
from mocap.data.sources import folder_sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.mismatch import fit_oracle

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_hybrid_calls_its_apf_and_ends_no_worse_than_local_on_a_mismatch_clip():
    body = mocap.load_body("paper22")
    seq = folder_sequence(body=body, path=str(REPO / "data" / "mismatch" / "gesture_turn"), images=False)
    F = 10
    gt = seq.gt
    # a good start: the oracle as a run's metrics fit it (the trust region's errors within
    # tests/clips/test_fit.py's tolerance, at a fraction of its time)
    start = fit_oracle(body, gt.joint_names, gt.joints[:F], None, gt.skeleton, method="tracked")
    scorer = NameScorer(body, gt)
    errors, calls = {}, None
    for name in ("local", "hybrid"):
        res = mocap.track(seq, tracker=name, body=body, init=start.chi[0], alpha=start.alpha, frames=F,
                          seed=0)
        chis = np.stack([e.chi for e in res.estimates])
        errors[name] = scorer.metrics(body.shaped(start.alpha), chis)["mpjpe_mm"]
        if name == "hybrid":
            calls = [bool(e.diagnostics.apf_called) for e in res.estimates[1:]]
    assert sum(calls) >= 1
    assert errors["hybrid"] <= errors["local"]
