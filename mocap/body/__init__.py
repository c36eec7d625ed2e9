"""The 3D morphable body model: PCA shape space, twist kinematic chain, LBS."""

from mocap.body.dofs import DofSpec, dofs_from_config
from mocap.body.model import BodyModel, BodyOutput, ShapedBody, load_body_model
from mocap.body.model_file import BodyModelData, BodyModelFileError, load_body_model_data


def load_body(name: str = "paper22", dtype: str | None = None, model_file: str | None = None) -> BodyModel:
    """A body shipped with mocap (``"paper22"``: the 22 DOFs of Zhang et al. 2013; ``"full"``:
    36 DOFs), from the package data :mod:`mocap.presets` (``body/<name>.yaml``). dtype and
    model_file override the preset's (default float32 and the shipped model)."""
    from mocap import presets

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
