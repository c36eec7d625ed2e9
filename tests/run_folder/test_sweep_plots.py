"""The sweep figures a person reads: one panel per dataset, short tracker names in the legend,
error bars mean ± std over seeds, the oracle as a dashed line, per-frame curves over seeds."""

import json

import numpy as np
import pytest
import yaml

from mocap.run_folder.sweep import collect, table_rows
from mocap.run_folder.sweep_plots import frames_figure, labels, plot, short_label, tradeoff_figure

# (tracker, particles, layers, energy terms) as a real run's metrics.json states them
TRACKERS = {"local": (0, 0, []), "apf_25x10": (25, 10, ["silhouette", "smoothness"]),
            "apf_prior": (25, 10, ["silhouette", "smoothness", "prior"])}
SECONDS = {"local": 0.45, "apf_25x10": 0.9, "apf_prior": 1.1}     # seed 0; seed 1 is 0.02 s slower
SHORT = {"local": "local", "apf_25x10": "APF 25×10", "apf_prior": "APF 25×10 + prior"}
ORACLE = {"mismatch_box": 5.9, "mismatch_walk": 7.2}
FRAMES = 5


def per_frame(data, tracker, seed):
    """A known per-frame error curve (mm) of one run."""
    base = {"mismatch_box": 20.0, "mismatch_walk": 30.0}[data]
    slope = {"local": 0.5, "apf_25x10": 6.0, "apf_prior": 3.0}[tracker]
    return [base + slope * f + 2.0 * seed * (f > 0) for f in range(FRAMES)]


def seal(root):
    """Mark each fake run complete as a finished run is: manifest.json with its files' checksums."""
    from mocap.run_folder.manifest import write_manifest

    for m in root.rglob("metrics.json"):
        write_manifest(m.parent, [n for n in ("motion.npz", "metrics.json") if (m.parent / n).is_file()])
    return root


def fake_sweep(root):
    """2 datasets x 3 trackers x 2 seeds, each run directory as experiments/track.py writes it
    (.hydra/overrides.yaml, metrics.json with the keys of a real mismatch run)."""
    for data in ORACLE:
        for tracker, (P, L, terms) in TRACKERS.items():
            for seed in (0, 1):
                d = root / f"{tracker}_{data}_s{seed}"
                (d / ".hydra").mkdir(parents=True)
                (d / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(
                    [f"tracker={tracker}", f"data={data}", f"seed={seed}", f"frames={FRAMES}",
                     "init.mode=tracker"]))
                pf = per_frame(data, tracker, seed)
                mpjpe = float(np.mean(pf))
                oracle = ORACLE[data]
                metrics = {
                    "tracker": tracker, "seed": seed, "data": data, "frames": FRAMES,
                    "mpjpe_mm": mpjpe, "mpjpe_std_mm": float(np.std(pf)), "per_frame_mm": pf,
                    "mpjpe_root_aligned_mm": mpjpe + 3.0, "pcp": 1.0, "frames_lost": 0,
                    "mismatch": {"raw_mm": mpjpe, "offset_removed_mm": mpjpe / 5, "limbs_mm": mpjpe,
                                 "limbs_offset_removed_mm": mpjpe / 5, "frames_lost": 0},
                    "oracle": {"raw_mm": oracle, "offset_removed_mm": 0.8, "limbs_mm": 3.5,
                               "limbs_offset_removed_mm": 0.6, "frames_lost": 0},
                    "sec_per_frame": SECONDS[tracker] + 0.02 * seed,
                    "energy_evals_per_frame": 250.0 * (P > 0), "particles": P, "layers": L,
                    "energy_terms": terms, "threads": 2}
                (d / "metrics.json").write_text(json.dumps(metrics))
    return root


@pytest.fixture
def sweep(tmp_path):
    got = collect(seal(fake_sweep(tmp_path / "sweep")))
    assert not got.problems and len(got.runs) == 12
    return got


def legend_texts(fig):
    (legend,) = fig.legends
    return [t.get_text() for t in legend.get_texts()]


def test_tradeoff_panels_legend_error_bars_and_oracle(sweep):
    import matplotlib.pyplot as plt

    fig = tradeoff_figure(table_rows(sweep.runs))
    try:
        assert [ax.get_title() for ax in fig.axes] == ["mismatch_box", "mismatch_walk"]
        assert legend_texts(fig) == [SHORT[t] for t in sorted(TRACKERS)] + ["oracle"]
        assert fig.axes[0].get_xscale() == "log"
        for ax in fig.axes:
            data = ax.get_title()
            bars = {c.get_label(): c for c in ax.containers}
            assert sorted(bars) == sorted(SHORT.values())
            for tracker, name in SHORT.items():
                errs = [np.mean(per_frame(data, tracker, s)) for s in (0, 1)]
                mean, std = np.mean(errs), np.std(errs, ddof=1)
                (segment,) = bars[name].lines[2][0].get_segments()
                assert segment[:, 1] == pytest.approx([mean - std, mean + std])
                x = segment[0, 0]
                assert x == pytest.approx(SECONDS[tracker] + 0.01)
            (oracle,) = [ln for ln in ax.get_lines() if ln.get_label() == "oracle"]
            assert oracle.get_linestyle() == "--" and oracle.get_ydata()[0] == pytest.approx(ORACLE[data])
            assert len(ax.texts) == 0                          # no annotations on the points
    finally:
        plt.close(fig)


def test_frames_curves_are_means_over_seeds_with_the_oracle(sweep):
    import matplotlib.pyplot as plt

    fig = frames_figure(sweep.runs)
    try:
        assert [ax.get_title() for ax in fig.axes] == ["mismatch_box", "mismatch_walk"]
        assert legend_texts(fig) == [SHORT[t] for t in sorted(TRACKERS)] + ["oracle"]
        for ax in fig.axes:
            data = ax.get_title()
            lines = {ln.get_label(): ln for ln in ax.get_lines()}
            for tracker, name in SHORT.items():
                curves = np.array([per_frame(data, tracker, s) for s in (0, 1)])
                assert lines[name].get_xdata() == pytest.approx(np.arange(FRAMES))
                assert lines[name].get_ydata() == pytest.approx(curves.mean(axis=0))
            assert lines["oracle"].get_ydata()[0] == pytest.approx(ORACLE[data])
            # one min-max band per tracker, spanning the seeds' extremes
            bands = ax.collections
            assert len(bands) == 3
            lo = min(min(per_frame(data, t, 0)) for t in TRACKERS)
            hi = max(max(per_frame(data, t, 1)) for t in TRACKERS)
            ys = np.concatenate([b.get_paths()[0].vertices[:, 1] for b in bands])
            assert ys.min() == pytest.approx(lo) and ys.max() == pytest.approx(hi)
    finally:
        plt.close(fig)


def test_plot_writes_both_readable_pngs(sweep, tmp_path):
    import matplotlib.image as mpimg

    plot(table_rows(sweep.runs), tmp_path / "ablation.png", runs=sweep.runs)
    for name in ("ablation.png", "ablation_frames.png"):
        img = mpimg.imread(tmp_path / name)
        # two 4-inch panels at 120 dpi side by side
        assert img.ndim == 3 and img.shape[1] == 960 and img.shape[0] > 400
    (tmp_path / "rows_only").mkdir()
    plot(table_rows(sweep.runs), tmp_path / "rows_only" / "ablation.png")
    assert sorted(p.name for p in (tmp_path / "rows_only").iterdir()) == ["ablation.png"]


def test_short_labels_for_overrides():
    row = {"tracker": "apf_prior", "data": "d", "particles_x_layers": "50x10",
           "energy_terms": "silhouette+smoothness+prior",
           "overrides": "tracker.particles=50 tracker.energy.prior=0.5"}
    # the budget is in the name; the other override is a short suffix, not the raw string
    assert short_label(row) == "APF 50×10 + prior (prior=0.5)"
    assert short_label({"tracker": "marker_apf", "overrides": "tracker.layers=4"}) == "marker APF (layers=4)"
    assert short_label({"tracker": "hybrid", "overrides": "-"}) == "hybrid"
    assert short_label({"tracker": "new_tracker", "overrides": "-"}) == "new_tracker"
    # the two priors of the real-motion comparison read apart
    real = {"tracker": "apf_prior_real", "particles_x_layers": "25x10",
            "energy_terms": "silhouette+smoothness+prior", "overrides": "-"}
    assert short_label(real) == "APF 25×10 + real prior"
    assert short_label({**real, "tracker": "apf_prior"}) == "APF 25×10 + prior"
    assert short_label({"tracker": "hybrid_kp", "overrides": "-"}) == "two-cue hybrid"
    noisy = [{"tracker": "local", "data": "d",
              "overrides": f"data.silhouette_noise={{holes:2,dilate_px:{k}}}"} for k in (3, 5)]
    cut = short_label(noisy[0])
    assert cut.startswith("local (silhouette_noise=") and cut.endswith("…)") and len(cut) < 45
    # cut values that would read the same in one dataset are left whole
    assert labels(noisy) == ["local (silhouette_noise={holes:2,dilate_px:3})",
                             "local (silhouette_noise={holes:2,dilate_px:5})"]


def test_runs_without_per_frame_errors_are_left_out_and_counted(sweep):
    import matplotlib.pyplot as plt

    runs = [dict(r) for r in sweep.runs]
    dropped = [r for r in runs if r["tracker"] == "local" and r["data"] == "mismatch_walk"]
    for r in dropped:
        del r["per_frame_mm"]
    fig = frames_figure(runs)
    try:
        walk = next(ax for ax in fig.axes if ax.get_title() == "mismatch_walk")
        assert "local" not in [ln.get_label() for ln in walk.get_lines()]
        assert f"{len(dropped)} run(s) with a joint error but no per_frame_mm left out" in \
            fig.legends[0].get_title().get_text()
    finally:
        plt.close(fig)


def test_a_sweep_without_ground_truth_still_gets_a_figure(tmp_path):
    import matplotlib.image as mpimg

    rows = [{"tracker": "local", "data": "video", "overrides": "-", "particles_x_layers": "-",
             "energy_terms": "-", "seeds": 1, "sec_per_frame": 0.3, "jitter_mm": 4.0}]
    plot(rows, tmp_path / "ablation.png", runs=[{"tracker": "local", "data": "video", "sec_per_frame": 0.3}])
    for name in ("ablation.png", "ablation_frames.png"):
        assert mpimg.imread(tmp_path / name).ndim == 3
