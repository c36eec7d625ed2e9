"""A run folder: one tracker over one sequence, written as ``motion.npz``, ``metrics.json`` and
``recording.rrd`` (:func:`run_tracking`), and what is read back from a finished one
(:mod:`mocap.run_folder.read`). Plain Python objects in, no Hydra: the command line
(``mocap track``, :mod:`mocap_cli`) composes the configuration and hands it over as a dict.

The names below are imported on first use, so that reading a run folder (its manifest, its
motion) does not import the trackers."""

_LAZY = {"run_body": "read", "run_config": "read", "run_sequence": "read", "write_json": "read",
         "RunDirectoryConflict": "tracking", "run_tracking": "tracking"}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    # plain import statements (no module name built from a string: nothing here imports by name)
    if _LAZY.get(name) == "read":
        from mocap.run_folder import read as module
    elif _LAZY.get(name) == "tracking":
        from mocap.run_folder import tracking as module
    else:
        raise AttributeError(f"module 'mocap.run_folder' has no attribute {name!r}")
    return getattr(module, name)
