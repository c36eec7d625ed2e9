"""A run folder: one tracker over one sequence, written as ``motion.npz``, ``metrics.json`` and
``recording.rrd`` (:func:`run_tracking`), and what is read back from a finished one
(:mod:`mocap.run_folder.read`). Plain Python objects in, no Hydra: the command line
(``mocap track``, :mod:`mocap_cli`) composes the configuration and hands it over as a dict."""

from mocap.run_folder.read import run_body, run_config, run_sequence, write_json
from mocap.run_folder.tracking import RunDirectoryConflict, run_tracking

__all__ = ["RunDirectoryConflict", "run_body", "run_config", "run_sequence", "run_tracking", "write_json"]
