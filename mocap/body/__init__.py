"""The 3D morphable body model: PCA shape space, twist kinematic chain, LBS.

The model's names below are imported on first use, so that the skeletons' and layouts' names
(:mod:`mocap.body.skeletons`, the command line's choices) do not import the numeric stack."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mocap.body.model import BodyModel

_LAZY = {"DofSpec": "dofs", "dofs_from_config": "dofs", "BodyModel": "model", "BodyOutput": "model",
         "ShapedBody": "model", "load_body_model": "model", "BodyModelData": "model_file",
         "BodyModelFileError": "model_file", "load_body_model_data": "model_file"}


def load_body(name: str = "paper22", dtype: str | None = None, model_file: str | None = None) -> BodyModel:
    """A body shipped with mocap (``"paper22"``: the 22 DOFs of Zhang et al. 2013; ``"full"``:
    36 DOFs), from the package data :mod:`mocap.presets` (``body/<name>.yaml``). dtype and
    model_file override the preset's (default float32 and the shipped model)."""
    from mocap import presets
    from mocap.body.model import load_body_model

    cfg = presets.read("body", name)
    cfg.pop("_target_", None)
    if dtype is not None:
        cfg["dtype"] = dtype
    if model_file is not None:
        cfg["model_file"] = model_file
    return load_body_model(**cfg)


__all__ = [
    "BodyModel", "BodyModelData", "BodyModelFileError", "BodyOutput", "DofSpec", "ShapedBody",
    "dofs_from_config", "load_body", "load_body_model", "load_body_model_data",
]


def __getattr__(name: str):
    # plain import statements (no module name built from a string: nothing here imports by name)
    module = _LAZY.get(name)
    if module == "dofs":
        from mocap.body import dofs as module
    elif module == "model":
        from mocap.body import model as module
    elif module == "model_file":
        from mocap.body import model_file as module
    else:
        raise AttributeError(f"module 'mocap.body' has no attribute {name!r}")
    return getattr(module, name)
