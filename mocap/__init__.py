"""mocap: multi-view human motion capture on a 3D morphable body model.

Packages (the layout is the architecture):
    body        PCA shape space, twist kinematic chain, linear blend skinning
    cameras     pinhole cameras, projection, rays, Plücker lines, epipolar geometry
    render      silhouette rasterizer, distance transforms, RGB rendering
    data        motion library, synthetic sequences, loaders for recordings
    energy      silhouette, smoothness and pose-prior energies
    trackers    local optimizer, annealed particle filter, hybrid and marker trackers
    eval        joint error, MMTA/MMTP
    recording   Rerun sinks (the only package that imports rerun)
    presets     package data: body DOF definitions and camera rigs

Python API (no Hydra, no repository needed): :func:`load_body`, :func:`synthetic_sequence`,
:func:`track` (see :mod:`mocap.api`).
"""

__version__ = "0.1.0"

_API = {"load_body": "mocap.body", "track": "mocap.api", "synthetic_sequence": "mocap.api"}


def __getattr__(name: str):
    if name in _API:                     # imported on first use: `import mocap` stays light
        import importlib

        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'mocap' has no attribute {name!r}")
