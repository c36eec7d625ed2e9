"""Per-frame values gathered and sent to Rerun in batches (``send_columns``): one chunk per
entity and batch instead of one ``log`` call (and one small chunk) per value and frame.

    cols = Columns()
    cols.scalar("plots/error/mpjpe_mm", f, 12.5)
    cols.add("world/body/estimate", rr.Mesh3D, f, vertex_positions=V)      # (V, 3): one row
    cols.send(rec)                                                          # and cleared

A row's field is either one value per row (a number, a string) or an array whose first axis
is the row's length (points, vertices, line strips); rows of an entity may differ in length.
"""

from __future__ import annotations

import numpy as np
import rerun as rr


class Columns:
    def __init__(self) -> None:
        # (entity, timeline, archetype) -> (times, {field: [row values]})
        self._rows: dict[tuple[str, str, type], tuple[list[int], dict[str, list]]] = {}
        self.pending = 0
        self.nbytes = 0          # about what the gathered rows hold (arrays and blobs)

    def add(self, entity: str, archetype: type, t: int, timeline: str = "frame", **fields) -> None:
        """One row of ``archetype``'s ``fields`` for ``entity`` at time ``t`` on ``timeline``."""
        times, values = self._rows.setdefault((entity, timeline, archetype), ([], {k: [] for k in fields}))
        if values.keys() != fields.keys():
            raise ValueError(f"{entity}: fields {sorted(fields)} differ from the earlier rows' "
                             f"{sorted(values)}")
        times.append(int(t))
        for k, v in fields.items():
            values[k].append(v)
            self.nbytes += v.nbytes if isinstance(v, np.ndarray) else len(v) if isinstance(v, bytes) else 8
        self.pending += 1

    def scalar(self, entity: str, t: int, value: float, timeline: str = "frame") -> None:
        self.add(entity, rr.Scalars, t, timeline, scalars=float(value))

    def text(self, entity: str, t: int, text: str, level: str = "INFO") -> None:
        self.add(entity, rr.TextLog, t, text=text, level=level)

    def send(self, rec: rr.RecordingStream) -> None:
        """Send every gathered row (one ``send_columns`` per entity) and forget them."""
        for (entity, timeline, archetype), (times, values) in self._rows.items():
            lengths = None
            fields = {}
            for k, rows in values.items():
                if isinstance(rows[0], np.ndarray) and rows[0].ndim >= 1:
                    n = [len(r) for r in rows]
                    if lengths is not None and n != lengths:
                        raise ValueError(f"{entity}: fields of one row differ in length")
                    lengths = n
                    fields[k] = np.concatenate(rows)     # line strips (N, 2, 3): one array, not a list
                else:
                    fields[k] = rows
            columns = archetype.columns(**fields)
            if lengths is not None:
                columns = columns.partition(lengths)
            rec.send_columns(entity, indexes=[rr.TimeColumn(timeline, sequence=times)], columns=columns)
        self._rows.clear()
        self.pending = self.nbytes = 0
