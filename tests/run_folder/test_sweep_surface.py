"""Surface columns in the ablation table and a surface panel beside the joint error."""

import pytest

from mocap.run_folder.sweep import markdown, table_rows
from mocap.run_folder.sweep_plots import tradeoff_figure


def _run(tracker, data, seed, joint, surface, oracle, iou):
    return {"tracker": tracker, "data": data, "seed": seed, "sec_per_frame": 1.0 + seed,
            "config": {"tracker": tracker, "data": data, "seed": seed}, "mpjpe_mm": joint,
            "oracle": {"raw_mm": 10.0}, "surface_to_mesh_mm": surface, "surface_to_mesh_p90_mm": 2 * surface,
            "mesh_to_surface_mm": surface + 1, "surface_oracle_mm": oracle, "silhouette_iou": iou}


def test_surface_columns_are_means_over_seeds_and_ratios_to_the_surface_oracle():
    runs = [_run("hybrid_kp", "real_a", 0, 20.0, 9.0, 4.0, 0.80),
            _run("hybrid_kp", "real_a", 1, 22.0, 11.0, 4.0, 0.90),
            _run("marker_apf", "real_a", 0, 18.0, 12.0, 4.0, 0.70)]
    rows = {r["tracker"]: r for r in table_rows(runs)}
    assert rows["hybrid_kp"]["surface_to_mesh_mm"] == pytest.approx(10.0)
    assert rows["hybrid_kp"]["x_surface_oracle"] == pytest.approx(2.5)
    assert rows["hybrid_kp"]["silhouette_iou"] == pytest.approx(0.85)
    assert rows["marker_apf"]["mesh_to_surface_mm"] == pytest.approx(13.0)
    md = markdown(list(rows.values()), [], "t")
    for label in ("surface → tracked (mm)", "tracked → surface (mm)", "surface oracle (mm)",
                  "× surface oracle", "silhouette IoU"):
        assert label in md
    assert "0.850 ± 0.071" in md and "10.0 ± 1.4" in md


def test_a_surface_panel_sits_beside_each_joint_panel():
    runs = [_run("hybrid_kp", d, 0, 20.0, 9.0, 4.0, 0.8) for d in ("real_a", "real_b")]
    runs.append({"tracker": "local", "data": "mismatch_c", "seed": 0, "sec_per_frame": 1.0, "mpjpe_mm": 30.0,
                 "config": {"tracker": "local", "data": "mismatch_c", "seed": 0}})
    fig = tradeoff_figure(table_rows(runs))
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert titles == ["real_a", "real_a — surface", "real_b", "real_b — surface", "mismatch_c"]
    surface_ax = next(ax for ax in fig.axes if ax.get_title() == "real_a — surface")
    assert "surface" in surface_ax.get_ylabel()
    ys = [line.get_ydata()[0] for line in surface_ax.get_lines() if line.get_linestyle() == "--"]
    assert ys == [pytest.approx(4.0)]                                  # the surface oracle's line
