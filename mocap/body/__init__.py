"""The 3D morphable body model: PCA shape space, twist kinematic chain, LBS."""

from mocap.body.dofs import DofSpec, dofs_from_config
from mocap.body.model import BodyModel, BodyOutput, ShapedBody, load_body_model
from mocap.body.model_file import BodyModelData, BodyModelFileError, load_body_model_data

__all__ = [
    "BodyModel", "BodyModelData", "BodyModelFileError", "BodyOutput", "DofSpec", "ShapedBody",
    "dofs_from_config", "load_body_model", "load_body_model_data",
]
