"""Trackers: the local optimizer, the annealed particle filters, the hybrid and the marker
trackers, and the one contract every tracker keeps with the run (:mod:`mocap.trackers.contract`:
what it needs, its search budget, its self-initialisation, ``begin`` and ``track`` answering
person id -> estimate; a single-person tracker's ``initialize`` / ``step(frame) -> Estimate``
give it that through :class:`~mocap.trackers.contract.OnePerson`), and the one frame loop
(:func:`mocap.trackers.run.run_frames`)."""
