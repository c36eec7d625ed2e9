"""How a tracker recovers from an injected failure, from its per-frame errors."""

from __future__ import annotations

from collections.abc import Collection, Sequence

import numpy as np


def recovery_figures(per_frame_mm: Sequence[float], at: int, excluded: Collection[int] = (),
                     window: int = 5, factor: float = 2.0) -> dict:
    """The figures of one failure whose first affected frame is ``at``.

    per_frame_mm: (F,) error per frame (frame 0 the initialisation); excluded: frames the
    tracker never saw (a frame skip), left out of every count. Keys: at_frame;
    error_before_mm, the mean error of the last ``window`` seen frames before ``at``;
    error_at_mm; frames_to_recover, the number of seen frames from ``at`` on before the error
    is back under ``factor`` x error_before_mm (0: it never left; None: not recovered by the
    end); recovered_at_frame (None likewise).
    """
    errors = np.asarray(per_frame_mm, np.float64)
    if not 0 < at < len(errors):
        raise ValueError(f"failure at frame {at} outside the tracked frames 1..{len(errors) - 1}")
    seen = [f for f in range(len(errors)) if f not in set(excluded)]
    if at not in seen:
        raise ValueError(f"frame {at} was not seen by the tracker")
    i = seen.index(at)
    before = float(np.mean(errors[seen[max(0, i - window):i]]))
    after = [f for f in seen[i:] if errors[f] < factor * before]
    first = after[0] if after else None
    return {"at_frame": int(at), "error_before_mm": before, "error_at_mm": float(errors[at]),
            "frames_to_recover": None if first is None else seen[i:].index(first),
            "recovered_at_frame": first}
