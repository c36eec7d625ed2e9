"""Pose prior sources, the asset's metadata, and the train/held-out split of the real prior."""

from __future__ import annotations

import numpy as np
import pytest

from experiments.tools.real_prior import BANDAI_NAMCO_LICENCE
from mocap.clips.split import check_training_types, read_split
from mocap.energy.prior import PRIOR_FORMAT, ParzenPrior, PriorProvenance, default_prior_path, prior_path

SPLIT = read_split()


def test_prior_path_sources_and_unknown_source():
    assert prior_path("paper22", "procedural") == default_prior_path("paper22")
    assert prior_path("paper22", "procedural").name == "pose_prior_paper22.npz"
    assert prior_path("full", "real").name == "pose_prior_real_full.npz"
    assert prior_path("paper22", "real-paper-sigma").name == "pose_prior_real_paper_sigma_paper22.npz"
    assert prior_path("paper22", "real").parent == default_prior_path("paper22").parent
    with pytest.raises(ValueError, match="source 'mocap': available procedural, real, real-paper-sigma"):
        prior_path("paper22", "mocap")


def test_procedural_assets_are_old_format_and_still_load():
    for body in ("paper22", "full"):
        with np.load(default_prior_path(body)) as z:
            assert str(z["format"]) == "mocap-pose-prior-v1"
        p = ParzenPrior.load(default_prior_path(body))
        assert len(p.samples) == 100 and p.provenance == PriorProvenance()


def test_metadata_round_trips_through_the_file(tmp_path):
    rng = np.random.default_rng(0)
    prov = PriorProvenance(licence=BANDAI_NAMCO_LICENCE, motion_types=("bow", "walk"),
                           held_out_types=("punch",), clips=3, clips_sha256="ab" * 32, pool=50,
                           selection="uniform (20 of 50 frames)", retarget="v1", body="paper22")
    p = ParzenPrior.fit(rng.normal(size=(20, 4)), tuple("abcd"), source="test poses", provenance=prov)
    back = ParzenPrior.load(p.save(tmp_path / "p.npz"))
    assert back.provenance == prov and back.source == "test poses" and back.sigma == p.sigma
    np.testing.assert_array_equal(back.samples, p.samples)
    with np.load(tmp_path / "p.npz") as z:
        assert str(z["format"]) == PRIOR_FORMAT
        import json
        meta = json.loads(str(z["meta"]))
    assert meta["samples"] == 20 and meta["sigma"] == p.sigma and "non-commercial" in meta["licence"]


@pytest.mark.parametrize("source", ["real", "real-paper-sigma"])
def test_shipped_real_priors_carry_licence_and_no_held_out_type(source):
    split = read_split()
    for body in ("paper22", "full"):
        path = prior_path(body, source)
        if body == "full" and not path.is_file():
            continue                        # paper22's is the one the trackers need
        p = ParzenPrior.load(path)
        prov = p.provenance
        assert prov.licence == BANDAI_NAMCO_LICENCE and prov.body == body
        assert prov.motion_types and not set(prov.motion_types) & set(split.held_out)
        assert set(prov.motion_types) <= set(split.train)
        assert tuple(prov.held_out_types) == split.held_out
        assert prov.clips > 0 and len(prov.clips_sha256) == 64 and prov.pool >= len(p.samples)
        assert (path.parent / "NOTICE-pose_prior_real.txt").is_file()


def test_split_file_is_disjoint_and_the_leak_check_raises():
    assert SPLIT.train and SPLIT.held_out and not set(SPLIT.train) & set(SPLIT.held_out)
    check_training_types(SPLIT.train, SPLIT)
    with pytest.raises(ValueError, match="punch are held out"):
        check_training_types(("walk", "punch"), SPLIT)
    with pytest.raises(ValueError, match="swim are not train types"):
        check_training_types(("walk", "swim"), SPLIT)


def test_real_presets_read_the_real_prior(body):
    """apf_prior_real and hybrid_prior_real evaluate E_P with the prior shipped from real motion
    (its samples, not the procedural ones); apf_prior and hybrid_prior with the procedural one;
    the hybrid without a prior has none."""
    from mocap.cameras import ring_rig
    from mocap.trackers.presets import make_tracker

    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=45, look_at=(0, 0, 0.9))
    real = ParzenPrior.load(prior_path(body.name, "real")).samples
    procedural = ParzenPrior.load(prior_path(body.name, "procedural")).samples
    assert real.shape != procedural.shape or not np.array_equal(real, procedural)
    for name, want in [("apf_prior_real", real), ("apf_prior", procedural),
                       ("hybrid_prior_real", real), ("hybrid_prior", procedural)]:
        tracker = make_tracker(name, body=body, rig=rig, rng=np.random.default_rng(0))
        np.testing.assert_array_equal(tracker.prior.parzen.samples, want, err_msg=name)
    assert make_tracker("hybrid", body=body, rig=rig, rng=np.random.default_rng(0)).prior is None
