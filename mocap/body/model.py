"""The runtime morphable body: PCA shape (Eq. 1), twist chain (Eq. 3-5) and LBS (Eq. 2).

Batch-first over particles. ``BodyModel.shaped(alpha)`` fixes a shape once and returns a
:class:`ShapedBody` whose ``pose(chi)`` is the hot path of every tracker;
``BodyModel.pose(chi, alpha)`` also accepts one shape per particle.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocap.body.dofs import DofSpec, check_joints, dofs_from_config, resolve_axes
from mocap.body.kinematics import chain_transforms, posed_joints
from mocap.body.lbs import lbs, lbs_apply, lbs_basis
from mocap.body.model_file import BodyModelData, load_body_model_data

ROOT_DOF_NAMES = ("root_v1", "root_v2", "root_v3", "root_w1", "root_w2", "root_w3")


@dataclass(frozen=True)
class BodyOutput:
    """A posed batch. vertices: (P, V, 3) and joints: (P, J, 3) world metres;
    transforms: (P, J, 4, 4) rest-to-world rigid transform of each joint."""

    vertices: np.ndarray
    joints: np.ndarray
    transforms: np.ndarray


def _as_batch(x: np.ndarray | Sequence[float], width: int, what: str, dtype) -> tuple[np.ndarray, bool]:
    a = np.asarray(x, dtype=dtype)
    single = a.ndim == 1
    if single:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{what} must have shape ({width},) or (P, {width}), got {np.shape(x)}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} contains NaN or inf")
    return a, single


@dataclass(frozen=True, eq=False)
class ShapedBody:
    """A body of fixed shape alpha, ready to pose many particles.

    rest_vertices: (V, 3); rest_joints: (J, 3) (the shape's, plus ``joint_offsets`` where
    given); axes: (D, 3) DOF axes in the rest frame, resolved from ``rest_joints``;
    joint_offsets: None or (J, 3) float64 metres, the rest-joint corrections this body carries.
    """

    model: BodyModel
    alpha: np.ndarray
    rest_vertices: np.ndarray
    rest_joints: np.ndarray
    axes: np.ndarray
    _basis_t: np.ndarray = field(repr=False)
    joint_offsets: np.ndarray | None = None

    def pose(self, chi: np.ndarray) -> BodyOutput:
        """chi: (P, D) or (D,) = (global twist (v, omega), joint angles in radians)."""
        m = self.model
        chi, _ = _as_batch(chi, m.num_dofs, "pose chi", m.dtype)
        G = chain_transforms(m.parents, m.dof_joint, self.axes, self.rest_joints,
                             chi[:, :6], chi[:, 6:])
        return BodyOutput(vertices=lbs_apply(self._basis_t, G),
                          joints=posed_joints(G, self.rest_joints), transforms=G)

    def is_for(self, alpha: np.ndarray, joint_offsets: np.ndarray | None = None) -> bool:
        """Whether this is the body of shape ``alpha`` (K,) and rest-joint corrections
        ``joint_offsets`` ((J, 3); None: none), to the bit: a cached body is built again otherwise."""
        if not np.array_equal(self.alpha, alpha):
            return False
        if self.joint_offsets is None or joint_offsets is None:
            return self.joint_offsets is None and joint_offsets is None
        return np.array_equal(self.joint_offsets, joint_offsets)

    def vertices(self, chi: np.ndarray, basis_t: np.ndarray | None = None) -> np.ndarray:
        """Posed vertices only: (P, D) -> (P, V, 3); with ``basis_t`` (4J, V') the vertices of
        a mesh riding on this body (e.g. :meth:`EnergyMesh.skinning_basis
        <mocap.body.energy_mesh.EnergyMesh.skinning_basis>`) instead of its own."""
        m = self.model
        chi, _ = _as_batch(chi, m.num_dofs, "pose chi", m.dtype)
        G = chain_transforms(m.parents, m.dof_joint, self.axes, self.rest_joints,
                             chi[:, :6], chi[:, 6:])
        return lbs_apply(self._basis_t if basis_t is None else basis_t, G)

    @property
    def skinning_basis(self) -> np.ndarray:
        """(4J, V): the basis this body is skinned with (:func:`mocap.body.lbs.lbs_basis`)."""
        return self._basis_t

    def joints(self, chi: np.ndarray) -> np.ndarray:
        """Joint positions only (no skinning): (P, D) -> (P, J, 3)."""
        m = self.model
        chi, _ = _as_batch(chi, m.num_dofs, "pose chi", m.dtype)
        G = chain_transforms(m.parents, m.dof_joint, self.axes, self.rest_joints,
                             chi[:, :6], chi[:, 6:])
        return posed_joints(G, self.rest_joints)


class BodyModel:
    """PCA body model with a configurable set of revolute DOFs.

    Pose vector chi: (D,) with D = 6 + number of DOFs, ``chi[:6]`` the global twist
    xi_0 = (v, omega) and ``chi[6:]`` the joint angles in ``dof_names[6:]`` order.
    Shape alpha: (K,) standardised PCA coefficients (see :mod:`mocap.body.model_file`).
    """

    def __init__(self, data: BodyModelData, dofs: Sequence[DofSpec], dtype=np.float32,
                 name: str = "body"):
        check_joints(dofs, data.joint_names)
        self.data, self.dofs, self.name = data, tuple(dofs), name
        self.dtype = np.dtype(dtype)
        self.joint_names = data.joint_names
        self.parents = data.joint_parents
        index = {n: i for i, n in enumerate(data.joint_names)}
        self.dof_joint = np.array([index[d.joint] for d in dofs], dtype=np.int64)
        self.dof_names = ROOT_DOF_NAMES + tuple(d.name for d in dofs)
        lim = np.array([[-np.inf, np.inf]] * 6 + [d.limits for d in dofs], dtype=np.float64)
        self.limits = lim                                   # (D, 2) radians, root unbounded
        self.faces = data.faces
        w = data.weights.astype(np.float64)
        self.weights = (w / w.sum(axis=1, keepdims=True)).astype(self.dtype)  # (V, J)
        self.part_labels = np.argmax(data.weights, axis=1)  # (V,) dominant joint per vertex
        self._basis = (data.stddev[:, None, None] * data.components).astype(np.float64)

    # -- sizes -------------------------------------------------------------------------
    @property
    def num_dofs(self) -> int:
        return 6 + len(self.dofs)

    @property
    def num_shape(self) -> int:
        return self.data.num_components

    @property
    def num_vertices(self) -> int:
        return self.data.num_vertices

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    def zero_pose(self, batch: int | None = None) -> np.ndarray:
        return np.zeros((self.num_dofs,) if batch is None else (batch, self.num_dofs), self.dtype)

    def dof_index(self, name: str) -> int:
        try:
            return self.dof_names.index(name)
        except ValueError:
            raise KeyError(f"unknown DOF '{name}' (known: {', '.join(self.dof_names)})") from None

    def joint_index(self, name: str) -> int:
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"unknown joint '{name}' (known: {', '.join(self.joint_names)})") from None

    # -- shape -------------------------------------------------------------------------
    def rest(self, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rest mesh and joints M(alpha): (K,) -> ((V, 3), (J, 3)); (P, K) -> batched."""
        a, single = _as_batch(alpha, self.num_shape, "shape alpha", np.float64)
        verts = self.data.mean + np.einsum("pk,kvc->pvc", a, self._basis)
        joints = self.data.joints_mean + np.einsum("pk,kjc->pjc", a, self.data.joints_basis)
        verts, joints = verts.astype(self.dtype), joints.astype(self.dtype)
        return (verts[0], joints[0]) if single else (verts, joints)

    def joint_offsets(self, offsets: np.ndarray | None) -> np.ndarray | None:
        """Checked rest-joint corrections: None (none) or (J, 3) finite metres -> float64."""
        if offsets is None:
            return None
        d = np.asarray(offsets, np.float64)
        if d.shape != (self.num_joints, 3):
            raise ValueError(f"joint_offsets must have shape ({self.num_joints}, 3), got {d.shape}")
        if not np.all(np.isfinite(d)):
            raise ValueError("joint_offsets contains NaN or inf")
        return d

    def corrected_joints(self, joints: np.ndarray, offsets: np.ndarray | None) -> np.ndarray:
        """Rest joints (..., J, 3) of the shape plus checked ``offsets`` (J, 3), in the model's
        dtype (the sum in float64); the joints themselves where ``offsets`` is None."""
        if offsets is None:
            return joints
        return (np.asarray(joints, np.float64) + offsets).astype(self.dtype)

    def shaped(self, alpha: np.ndarray | None = None, joint_offsets: np.ndarray | None = None) -> ShapedBody:
        """Fix the shape (default: the mean body) and precompute the skinning basis.

        joint_offsets: None or (J, 3) metres added to the shape's rest joints (a per-person
        skeleton inside the shape's outline): the posed joints and the skinning's rotation
        centres use the corrected joints, the DOF axes are resolved from them, and the rest mesh
        is the shape's (at the zero pose the surface is unchanged)."""
        a = np.zeros(self.num_shape) if alpha is None else np.asarray(alpha, np.float64)
        if a.shape != (self.num_shape,):
            raise ValueError(f"shape alpha must have shape ({self.num_shape},), got {a.shape}")
        d = self.joint_offsets(joint_offsets)
        verts, joints = self.rest(a)
        joints = self.corrected_joints(joints, d)
        return ShapedBody(model=self, alpha=a, rest_vertices=verts, rest_joints=joints,
                          axes=resolve_axes(self.dofs, self.joint_names, joints),
                          _basis_t=lbs_basis(self.weights, verts), joint_offsets=d)

    # -- pose --------------------------------------------------------------------------
    def pose(self, chi: np.ndarray, alpha: np.ndarray | None = None,
             joint_offsets: np.ndarray | None = None) -> BodyOutput:
        """Pose a batch; alpha (K,) shared or (P, K) one per particle; joint_offsets: None or
        (J, 3) rest-joint corrections shared by the batch (:meth:`shaped`)."""
        chi, _ = _as_batch(chi, self.num_dofs, "pose chi", self.dtype)
        if alpha is None or np.ndim(alpha) == 1:
            return self.shaped(alpha, joint_offsets).pose(chi)
        a, _ = _as_batch(alpha, self.num_shape, "shape alpha", np.float64)
        if len(a) != len(chi):
            raise ValueError(f"{len(a)} shapes for {len(chi)} poses")
        verts, joints = self.rest(a)
        joints = self.corrected_joints(joints, self.joint_offsets(joint_offsets))
        axes = resolve_axes(self.dofs, self.joint_names, joints)
        G = chain_transforms(self.parents, self.dof_joint, axes, joints, chi[:, :6], chi[:, 6:])
        return BodyOutput(vertices=lbs(self.weights, verts, G),
                          joints=posed_joints(G, joints), transforms=G)


def load_body_model(dofs: Sequence[Mapping] | Sequence[DofSpec], model_file: str | Path | None = None,
                    dtype: str = "float32", name: str = "body") -> BodyModel:
    """Body model from configuration (``mocap/presets/body/*.yaml``): a DOF list and a model file."""
    specs = tuple(d if isinstance(d, DofSpec) else None for d in dofs)
    if any(s is None for s in specs):
        specs = dofs_from_config(dofs)
    return BodyModel(load_body_model_data(model_file), specs, dtype=np.dtype(dtype), name=name)
