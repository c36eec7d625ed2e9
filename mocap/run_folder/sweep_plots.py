"""Figures of a sweep for a person to read (matplotlib, Agg backend, imported when drawing).

- :func:`tradeoff_figure` (``ablation.png``): one panel per dataset (sequence); the joint error
  (MPJPE, the table's headline) against time per frame (log axis), one marker per table row
  (tracker, its budget and the overrides that vary in the sweep), error bars mean ± std over
  seeds, the oracle (our body fitted to the true joints, ``metrics.json["oracle"]["raw_mm"]``)
  as a dashed line where known; beside it, for data with a true surface, the surface error
  (true surface -> tracked mesh, ``surface_to_mesh_mm``) with the surface oracle's line.
- :func:`frames_figure` (``ablation_frames.png``): one panel per dataset; each row's per-frame
  error (``metrics.json["per_frame_mm"]``, frame 0 the initial pose), the mean over seeds as a
  line and their min–max as a band; the oracle's mean as a dashed line.

Legends hold short names (:func:`short_label`), below the panels; no text on the points.
The rows are those of :func:`mocap.run_folder.sweep.table_rows` and the runs are grouped the same
way (:func:`mocap.run_folder.sweep.group_runs`), so a legend entry is a table row.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mocap.run_folder.sweep import group_runs

PANEL_IN = (4.0, 3.4)       # inches per panel (width, height)
DPI = 120
MAX_COLUMNS = 3             # panels per figure row
MARKERS = "osD^vP*Xph<>"
SUFFIX_VALUE_CHARS = 14     # an override value longer than this is cut (unless names would collide)
# overrides already visible in a name that shows the search budget (APF P×L)
BUDGET_KEYS = ("particles", "layers")
NAMES = {"local": "local", "hybrid": "hybrid", "marker_apf": "marker APF", "hybrid_kp": "two-cue hybrid",
         "hybrid_prior": "hybrid + prior", "hybrid_prior_real": "hybrid + real prior"}


def _budget(particles_x_layers: str) -> tuple[int, int] | None:
    try:
        p, layers = (int(v) for v in str(particles_x_layers).split("x"))
    except ValueError:
        return None
    return (p, layers) if p > 0 else None


def short_name(tracker: str, particles_x_layers: str = "-", energy_terms: str = "-") -> str:
    """A tracker's short name: "local", "hybrid", "marker APF"; an annealed particle filter by
    its budget and prior ("APF 25×10 + prior"; "+ real prior" for a preset named ``*_real``,
    the prior learned from real motion); any other tracker by its own name.
    particles_x_layers: "25x10" or "-"; energy_terms: "silhouette+smoothness+prior" or "-"."""
    if tracker in NAMES:
        return NAMES[tracker]
    budget = _budget(particles_x_layers)
    if tracker.startswith("apf") and budget:
        prior = " + prior" if "prior" in str(energy_terms).split("+") else ""
        prior = " + real prior" if prior and tracker.endswith("_real") else prior
        return f"APF {budget[0]}×{budget[1]}{prior}"
    return tracker


def _suffix_items(overrides: str, budget_in_name: bool, cut: bool) -> list[str]:
    items = []
    for o in ([] if overrides in ("", "-") else overrides.split(" ")):
        key, _, value = o.partition("=")
        leaf = key.split(".")[-1]
        if budget_in_name and key.startswith("tracker.") and leaf in BUDGET_KEYS:
            continue
        if cut and len(value) > SUFFIX_VALUE_CHARS:
            value = value[:SUFFIX_VALUE_CHARS - 1] + "…"
        items.append(f"{leaf}={value}")
    return items


def short_label(row: dict, cut: bool = True) -> str:
    """A table row's legend label: its tracker's short name and, when the sweep varies
    overrides, their last key part and value ("local (views=[0,2,4,6])"); cut: shorten long
    values."""
    name = short_name(row["tracker"], row.get("particles_x_layers", "-"), row.get("energy_terms", "-"))
    budget_in_name = name.startswith("APF ")
    items = _suffix_items(row.get("overrides", "-"), budget_in_name, cut)
    return f"{name} ({', '.join(items)})" if items else name


def labels(rows: Sequence[dict]) -> list[str]:
    """short_label of each row; values are left whole where cutting them would make two
    different rows of one dataset read the same."""
    out = [short_label(r) for r in rows]
    seen: dict[tuple, set] = {}
    for r, lab in zip(rows, out, strict=True):
        seen.setdefault((r.get("data", ""), lab), set()).add(short_label(r, cut=False))
    return [short_label(r, cut=False) if len(seen[(r.get("data", ""), lab)]) > 1 else lab
            for r, lab in zip(rows, out, strict=True)]


def _styles(names: Sequence[str]) -> dict[str, dict]:
    import matplotlib

    colors = matplotlib.colormaps["tab10"].colors
    return {n: {"color": colors[i % len(colors)], "marker": MARKERS[i % len(MARKERS)]}
            for i, n in enumerate(dict.fromkeys(names))}


def _figure(n_panels: int, columns: int = MAX_COLUMNS):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = min(max(n_panels, 1), columns)
    nrows = max(1, math.ceil(n_panels / cols))
    fig, axes = plt.subplots(nrows, cols, figsize=(PANEL_IN[0] * cols, PANEL_IN[1] * nrows + 0.9),
                             dpi=DPI, layout="constrained", squeeze=False)
    for ax in axes.flat[n_panels:]:
        ax.remove()
    return fig, list(axes.flat[:n_panels])


def _legend(fig, axes, title: str | None) -> None:
    handles, names = {}, []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in handles:
                handles[lab] = h
                names.append(lab)
    if "oracle" in names:                                  # last, after the trackers
        names.remove("oracle")
        names.append("oracle")
    if names:
        fig.legend([handles[n] for n in names], names, loc="outside lower center",
                   ncols=_legend_columns(names, fig.get_figwidth()), title=title, fontsize=9,
                   title_fontsize=9, frameon=False)


def _legend_columns(names: Sequence[str], width_in: float) -> int:
    """As many columns as fit the figure's width (at 9 pt about 0.075 in per character plus
    0.7 in for the handle and the gap), all in one row when they fit."""
    for cols in range(len(names), 1, -1):
        rows = [names[i::cols] for i in range(cols)]         # matplotlib fills column by column
        widths = [0.7 + 0.075 * max(len(n) for n in col) for col in rows if col]
        if sum(widths) <= 0.95 * width_in:
            return cols
    return 1


def _empty(message: str):
    fig, (ax,) = _figure(1)
    ax.axis("off")
    ax.text(0.5, 0.5, message, ha="center", va="center", wrap=True)
    return fig


def _datasets(items: Sequence[dict]) -> list[str]:
    return list(dict.fromkeys(r.get("data", "") for r in items))


# tick mantissas on a log axis spanning less than two decades, finest first
NICE = ((1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0), (1.0, 1.5, 2.0, 3.0, 5.0), (1.0, 2.0, 5.0),
        (1.0, 3.0))
MAX_TICKS = 7


def _plain_log_axis(ax, times: Sequence[float]) -> None:
    """A log time axis with plain numbers (not 1.1x10^0, ...); over less than two decades, where
    a log axis labels one or two ticks, ticks at the finest of 1, 1.2, 1.5, 2, ... x 10^k that
    gives at most MAX_TICKS."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    ax.set_xscale("log")
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    ax.xaxis.set_major_formatter(plain)
    ax.xaxis.set_minor_formatter(NullFormatter())
    times = [t for t in times if t > 0]
    if not times:
        return
    lo, hi = min(times) / 1.4, max(times) * 1.4
    ax.set_xlim(lo, hi)
    if hi >= 100 * lo:
        return
    decades = range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1)
    for mantissas in NICE:
        ticks = [t for k in decades for m in mantissas if lo <= (t := float(f"{m * 10.0 ** k:.6g}")) <= hi]
        if len(ticks) <= MAX_TICKS:
            break
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_minor_locator(NullLocator())


def _oracle(values: Sequence[float | None]) -> float | None:
    vals = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else None


def _seed_note(counts: Sequence[int]) -> str:
    lo, hi = min(counts), max(counts)
    n = f"{lo}" if lo == hi else f"{lo}–{hi}"
    return f"mean ± std over seeds (n = {n})" if hi > 1 else "one seed per point (no error bars)"


def tradeoff_figure(rows: Sequence[dict]):
    """rows: :func:`mocap.run_folder.sweep.table_rows` -> a Figure with one axes per dataset
    holding a joint error (rows with ``mpjpe_mean_mm``)."""
    rows = [r for r in rows if "mpjpe_mean_mm" in r]
    if not rows:
        return _empty("no run has a joint error (no ground truth): see ablation.md")
    names = labels(rows)
    style = _styles(names)
    datasets = _datasets(rows)
    # beside each dataset's joint error, its surface error where the data has a true surface
    panels = [(d, kind) for d in datasets for kind in ("joints", "surface")
              if kind == "joints" or any("surface_to_mesh_mm" in r for r in rows if r.get("data", "") == d)]
    fig, axes = _figure(len(panels), 2 if len(panels) > len(datasets) else MAX_COLUMNS)
    for ax, (data, kind) in zip(axes, panels, strict=True):
        mean_key, std_key, oracle_key = (("mpjpe_mean_mm", "mpjpe_std_mm", "oracle_mm") if kind == "joints"
                                         else ("surface_to_mesh_mm", "surface_to_mesh_mm_std",
                                               "surface_oracle_mm"))
        mine = [(r, n) for r, n in zip(rows, names, strict=True)
                if r.get("data", "") == data and mean_key in r]
        top = 0.0
        for r, n in mine:
            std = r.get(std_key)
            ax.errorbar(r["sec_per_frame"], r[mean_key], yerr=[[std], [std]] if std else None,
                        fmt=style[n]["marker"], color=style[n]["color"], ms=7, capsize=4, label=n)
            top = max(top, r[mean_key] + (std or 0.0))
        oracle = _oracle([r.get(oracle_key) for r, _ in mine])
        if oracle is not None:
            ax.axhline(oracle, ls="--", color="0.3", lw=1.2, label="oracle")
            top = max(top, oracle)
        _plain_log_axis(ax, [r["sec_per_frame"] for r, _ in mine])
        ax.set_ylim(0, 1.12 * top if top > 0 else 1.0)
        ax.set_title((data or "(unnamed data)") + (" — surface" if kind == "surface" else ""))
        ax.set_xlabel("time per frame (s, log scale)")
        ax.set_ylabel("joint error, MPJPE (mm)" if kind == "joints" else "true surface → tracked mesh (mm)")
        ax.grid(True, which="both", alpha=0.3)
    _legend(fig, axes, _seed_note([r["seeds"] for r in rows]))
    return fig


def frames_figure(runs: Sequence[dict]):
    """runs: metrics.json contents (:func:`mocap.run_folder.sweep.collect`) -> a Figure with one
    axes per dataset: per-frame joint error of each table row (runs with ``per_frame_mm``)."""
    groups = [(key, [r for r in rs if r.get("per_frame_mm")])
              for key, rs in group_runs([r for r in runs if r.get("per_frame_mm")]).items()]
    if not groups:
        return _empty("no run holds per-frame joint errors (no ground truth): see ablation.md")
    heads = [{"tracker": k[0], "data": k[1], "overrides": k[2], "particles_x_layers": k[3],
              "energy_terms": k[4]} for k, _ in groups]
    names = labels(heads)
    style = _styles(names)
    datasets = _datasets(heads)
    fig, axes = _figure(len(datasets))
    for ax, data in zip(axes, datasets, strict=True):
        mine = [(rs, n) for (_, rs), h, n in zip(groups, heads, names, strict=True) if h["data"] == data]
        for rs, n in mine:
            curves = per_frame_matrix(rs)
            x = np.arange(curves.shape[1])
            c = style[n]["color"]
            # hollow markers: curves that coincide (a hybrid that never called its APF and the
            # local tracker) still show both
            ax.plot(x, np.nanmean(curves, axis=0), color=c, lw=1.5, marker=style[n]["marker"],
                    ms=6 if len(x) <= 40 else 0, mfc="none", mew=1.4, label=n)
            if len(rs) > 1:
                ax.fill_between(x, np.nanmin(curves, axis=0), np.nanmax(curves, axis=0), color=c,
                                alpha=0.18, lw=0)
        oracle = _oracle([r.get("oracle", {}).get("raw_mm") for rs, _ in mine for r in rs])
        if oracle is not None:
            ax.axhline(oracle, ls="--", color="0.3", lw=1.2, label="oracle")
        ax.set_ylim(bottom=0)
        ax.set_title(data or "(unnamed data)")
        ax.set_xlabel("frame (0: initial pose)")
        ax.set_ylabel("joint error, MPJPE (mm)")
        ax.grid(True, alpha=0.3)
    counts = [len(rs) for _, rs in groups]
    lo, hi = min(counts), max(counts)
    note = (f"line: mean over seeds (n = {lo}{'' if lo == hi else f'–{hi}'}), band: min–max"
            if hi > 1 else "one seed per line")
    if any(o is not None for o in (_oracle([r.get("oracle", {}).get("raw_mm")]) for r in runs)):
        note += "; oracle: its mean over the sequence"
    # runs scored against ground truth before metrics.json kept per-frame errors: re-score them
    # (mocap rescore) to draw them
    missing = sum(1 for r in runs if "mpjpe_mm" in r and not r.get("per_frame_mm"))
    if missing:
        note += f"\n{missing} run(s) with a joint error but no per_frame_mm left out (re-score them)"
    _legend(fig, axes, note)
    return fig


def per_frame_matrix(runs: Sequence[dict]) -> np.ndarray:
    """runs' ``per_frame_mm`` lists -> (R, F) mm, NaN-padded to the longest run."""
    F = max(len(r["per_frame_mm"]) for r in runs)
    out = np.full((len(runs), F), np.nan)
    for i, r in enumerate(runs):
        out[i, :len(r["per_frame_mm"])] = np.asarray(r["per_frame_mm"], float)
    return out


def save(fig, path: str | Path) -> Path:
    import matplotlib.pyplot as plt

    path = Path(path)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def write_plots(rows: Sequence[dict], runs: Sequence[dict] | None, out_dir: str | Path) -> list[Path]:
    """ablation.png from ``rows`` and, when ``runs`` are given, ablation_frames.png, in out_dir."""
    out_dir = Path(out_dir)
    written = [save(tradeoff_figure(rows), out_dir / "ablation.png")]
    if runs is not None:
        written.append(save(frames_figure(runs), out_dir / "ablation_frames.png"))
    return written


def plot(rows: list[dict], path: Path, runs: list[dict] | None = None) -> None:
    """ablation.png at ``path`` (:func:`tradeoff_figure`: per dataset, error against time per
    frame, the oracle as a line) and, when ``runs`` (:func:`mocap.run_folder.sweep.collect`'s)
    are given, ablation_frames.png beside it (per-frame error curves)."""
    path = Path(path)
    save(tradeoff_figure(rows), path)
    if runs is not None:
        save(frames_figure(runs), path.with_name("ablation_frames.png"))
