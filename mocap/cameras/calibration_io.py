"""Read and write camera calibrations.

Three formats, all world-to-camera OpenCV convention (``x_cam = R @ x_world + t``, metres):

* **mocap** (ours), JSON (``.json``) or YAML (``.yaml``/``.yml``), same schema::

      {"cameras": [{"name": str, "K": 3x3, "dist": [k1, k2, p1, p2, k3], "R": 3x3,
                    "t": [3], "width": int, "height": int}, ...]}

  ``dist`` may be shorter (zero-padded) or absent (no distortion); everything else is
  required. Floats are written with ``repr`` so a round trip is exact.
* **OpenCV FileStorage** (YAML starting with ``%YAML:1.0`` / ``%YAML 1.2`` or containing
  ``!!opencv-matrix``, or ``.xml``), read/written with ``cv2.FileStorage``. Layout: one
  top-level sequence ``cameras`` of maps, one per camera, with the keys of our schema::

      cameras:
         - name: "cam_00"
           width: 640
           height: 480
           K: !!opencv-matrix {rows: 3, cols: 3, dt: d, data: [...]}
           dist: !!opencv-matrix {rows: 1, cols: 5, dt: d, data: [...]}
           R: !!opencv-matrix {rows: 3, cols: 3, dt: d, data: [...]}
           t: !!opencv-matrix {rows: 3, cols: 1, dt: d, data: [...]}

  Matrices may also be plain (nested) sequences when read. OpenCV writes doubles with 17
  significant digits, so a round trip is exact.
* **Pose2Sim / anipose TOML** (``.toml``): one table per camera (key arbitrary, order kept)
  with ``name`` (default: the table key), ``size`` [width, height], ``matrix`` K,
  ``distortions`` [k1, k2, p1, p2(, k3)], ``rotation`` Rodrigues vector (a 3x3 matrix is
  also accepted), ``translation`` metres, ``fisheye`` (only false is supported); the tables
  ``metadata``, ``capture_volume``, ``charuco`` and ``checkerboard`` are not cameras. Written
  with 17 significant digits; the rotation goes through Rodrigues, so a round trip is exact
  only to ~1e-15.

Every problem raises :class:`CalibrationError` (a ValueError) naming the file, the camera
and the field in the file's own vocabulary, e.g.
``"calib.toml: camera 'cam_01': field 'matrix' missing"``. Besides the camera checks
(shapes, NaN, orthonormal rotation, positive focal lengths and image size) the principal
point must lie inside the image, which catches a size for another resolution or with
width and height swapped (a principal point more than a quarter of the image away from the
centre only warns).
"""

from __future__ import annotations

import json
import re
import tomllib
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np
import yaml

from mocap.cameras.camera import (
    Camera,
    InvalidCameraError,
    Rig,
    rodrigues_from_rotation,
    rotation_from_rodrigues,
)
from mocap.checks import MAX_IMAGE_SIDE
from mocap.safe_files import name_problem

PathLike = str | Path
ImageSizes = Mapping[str, Sequence[int]] | Sequence[Sequence[int]]

_TOML_FIELDS = {"name": "name", "K": "matrix", "dist": "distortions", "R": "rotation",
                "t": "translation", "width": "size", "height": "size"}
_TOML_NON_CAMERA_TABLES = ("metadata", "capture_volume", "charuco", "checkerboard")


class CalibrationError(ValueError):
    """A calibration file is unreadable or invalid. ``path``, ``camera`` and ``field`` (the
    last two None when not applicable) say where."""

    def __init__(self, path: PathLike, reason: str, camera: str | None = None,
                 field: str | None = None):
        where = [str(path)]
        if camera is not None:
            where.append(f"camera {camera!r}")
        if field is not None:
            where.append(f"field {field!r}")
        sep = " " if reason == "missing" else ": "
        super().__init__(": ".join(where) + sep + reason)
        self.path = str(path)
        self.camera = camera
        self.field = field
        self.reason = reason


# --- shared validation -------------------------------------------------------------------------


def _build_camera(path: PathLike, label: str, fields: Mapping[str, str], **values) -> Camera:
    """Camera(**values), turning InvalidCameraError into CalibrationError with the file's
    field names (``fields`` maps Camera fields to them)."""
    try:
        return Camera(**values)
    except InvalidCameraError as exc:
        raise CalibrationError(path, exc.reason, label, fields.get(exc.field, exc.field)) from None


def _check_rig(path: PathLike, cams: list[Camera], fields: Mapping[str, str],
               image_sizes: ImageSizes | None) -> Rig:
    if not cams:
        raise CalibrationError(path, "no cameras")
    seen: set[str] = set()
    for cam in cams:
        problem = name_problem(cam.name)
        if problem is not None:       # a camera's name becomes a file name (pose/<name>_json, masks/<name>)
            raise CalibrationError(path, f"camera name {problem}; refused (camera names become file names)",
                                   cam.name[:80], fields["name"])
        if max(cam.width, cam.height) > MAX_IMAGE_SIDE:
            raise CalibrationError(path, f"image size {cam.width}x{cam.height} is larger than any camera's "
                                         f"(at most {MAX_IMAGE_SIDE} px a side)", cam.name, fields["width"])
        if cam.name in seen:
            raise CalibrationError(path, "duplicate camera name", cam.name, fields["name"])
        seen.add(cam.name)
        cx, cy = cam.K[0, 2], cam.K[1, 2]
        for value, size, axis in ((cx, cam.width, "width"), (cy, cam.height, "height")):
            if not -0.5 <= value <= size - 0.5:
                raise CalibrationError(
                    path,
                    f"image size {cam.width}x{cam.height} does not match the principal point "
                    f"({cx:.1f}, {cy:.1f}), which lies outside the image (a size for another "
                    "resolution, or width and height swapped?)",
                    cam.name, fields[axis])
        off = max(abs(cx - (cam.width - 1) / 2) / cam.width,
                  abs(cy - (cam.height - 1) / 2) / cam.height)
        if off > 0.25:
            warnings.warn(
                f"{path}: camera {cam.name!r}: principal point ({cx:.1f}, {cy:.1f}) is far "
                f"from the centre of the {cam.width}x{cam.height} image (width and height "
                "swapped?)", stacklevel=3)
    if image_sizes is not None:
        if isinstance(image_sizes, Mapping):
            expected = [(c, image_sizes.get(c.name)) for c in cams]
        else:
            if len(image_sizes) != len(cams):
                raise CalibrationError(path, f"{len(cams)} cameras but {len(image_sizes)} "
                                             "expected image sizes")
            expected = list(zip(cams, image_sizes, strict=True))
        for cam, size in expected:
            if size is not None and tuple(int(s) for s in size) != cam.size:
                raise CalibrationError(
                    path, f"image size {cam.width}x{cam.height} does not match the expected "
                    f"{int(size[0])}x{int(size[1])}", cam.name, fields["width"])
    return Rig(tuple(cams))


def _read_text(path: PathLike) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(path, f"cannot read file ({exc})") from None


# --- our format (JSON / YAML) ------------------------------------------------------------------


def rig_to_dict(rig: Rig) -> dict:
    """Our schema as plain Python containers (floats, ints, str, lists)."""
    return {"cameras": [
        {"name": c.name, "K": c.K.tolist(), "dist": c.dist.tolist(), "R": c.R.tolist(),
         "t": c.t.tolist(), "width": c.width, "height": c.height}
        for c in rig
    ]}


def rig_from_dict(data: object, source: PathLike = "<dict>",
                  image_sizes: ImageSizes | None = None) -> Rig:
    """Parse our schema (see the module docstring); errors name ``source``."""
    if not isinstance(data, Mapping):
        raise CalibrationError(source, f"expected a mapping at the top level, got "
                                       f"{type(data).__name__}")
    if "cameras" not in data:
        raise CalibrationError(source, "missing", field="cameras")
    entries = data["cameras"]
    if not isinstance(entries, list):
        raise CalibrationError(source, "expected a list of cameras", field="cameras")
    identity = {f: f for f in _TOML_FIELDS}
    cams = []
    for i, entry in enumerate(entries):
        label = f"#{i}"
        if not isinstance(entry, Mapping):
            raise CalibrationError(source, "expected a mapping", label)
        if "name" in entry:
            label = str(entry["name"])
        for key in ("name", "K", "R", "t", "width", "height"):
            if key not in entry:
                raise CalibrationError(source, "missing", label, key)
        cams.append(_build_camera(source, label, identity, name=entry["name"], K=entry["K"],
                                  dist=entry.get("dist"), R=entry["R"], t=entry["t"],
                                  width=entry["width"], height=entry["height"]))
    return _check_rig(source, cams, identity, image_sizes)


def read_mocap_calibration(path: PathLike, image_sizes: ImageSizes | None = None) -> Rig:
    """Our format from ``.json`` or ``.yaml``/``.yml``."""
    text = _read_text(path)
    try:
        data = json.loads(text) if Path(path).suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        raise CalibrationError(path, f"cannot parse file ({exc})") from None
    return rig_from_dict(data, path, image_sizes)


def write_mocap_calibration(rig: Rig, path: PathLike) -> None:
    """Our format; JSON for ``.json``, YAML otherwise."""
    data = rig_to_dict(rig)
    if Path(path).suffix == ".json":
        text = json.dumps(data, indent=2) + "\n"
    else:
        text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    Path(path).write_text(text, encoding="utf-8")


# --- OpenCV FileStorage ------------------------------------------------------------------------


def _is_opencv_yaml(text: str) -> bool:
    return text.lstrip().startswith("%YAML:") or "!!opencv-matrix" in text


def _fs_array(node) -> np.ndarray | None:
    """A FileNode holding an !!opencv-matrix or a (nested) sequence of numbers."""
    if node.isMap():
        return node.mat()
    if node.isSeq():
        items = [node.at(i) for i in range(node.size())]
        if all(it.isSeq() for it in items):
            return np.array([[it.at(j).real() for j in range(it.size())] for it in items])
        if all(it.isReal() or it.isInt() for it in items):
            return np.array([it.real() for it in items])
    if node.isReal() or node.isInt():
        return np.array(node.real())
    return None


def read_opencv_calibration(path: PathLike, image_sizes: ImageSizes | None = None) -> Rig:
    """OpenCV FileStorage YAML/XML in the layout of the module docstring."""
    if not Path(path).is_file():
        raise CalibrationError(path, "cannot read file (no such file)")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:
        msg = str(exc.__cause__ or exc).strip().splitlines()[-1]
        raise CalibrationError(path, f"cannot parse OpenCV FileStorage ({msg})") from None
    if not fs.isOpened():
        raise CalibrationError(path, "cannot open as OpenCV FileStorage")
    try:
        seq = fs.getNode("cameras")
        if seq.empty():
            raise CalibrationError(path, "missing", field="cameras")
        if not seq.isSeq():
            raise CalibrationError(path, "expected a sequence of cameras", field="cameras")
        identity = {f: f for f in _TOML_FIELDS}
        cams = []
        for i in range(seq.size()):
            node = seq.at(i)
            label = f"#{i}"
            if not node.isMap():
                raise CalibrationError(path, "expected a map", label)
            if not node.getNode("name").empty():
                label = node.getNode("name").string()
            values: dict[str, object] = {}
            for key in ("name", "K", "dist", "R", "t", "width", "height"):
                child = node.getNode(key)
                if child.empty():
                    if key == "dist":
                        values[key] = None
                        continue
                    raise CalibrationError(path, "missing", label, key)
                if key == "name":
                    values[key] = child.string()
                elif key in ("width", "height"):
                    if not (child.isInt() or child.isReal()):
                        raise CalibrationError(path, "expected a number", label, key)
                    values[key] = child.real()
                else:
                    arr = _fs_array(child)
                    if arr is None:
                        raise CalibrationError(path, "expected a matrix", label, key)
                    values[key] = arr
            cams.append(_build_camera(path, label, identity, **values))
    finally:
        fs.release()
    return _check_rig(path, cams, identity, image_sizes)


def write_opencv_calibration(rig: Rig, path: PathLike) -> None:
    """OpenCV FileStorage (YAML for .yaml/.yml, XML for .xml) in the documented layout."""
    if Path(path).suffix not in (".yaml", ".yml", ".xml"):
        raise ValueError(f"{path}: OpenCV FileStorage calibrations must be .yaml, .yml or .xml")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    try:
        fs.startWriteStruct("cameras", cv2.FileNode_SEQ)
        for c in rig:
            fs.startWriteStruct("", cv2.FileNode_MAP)
            fs.write("name", c.name)
            fs.write("width", c.width)
            fs.write("height", c.height)
            fs.write("K", c.K)
            fs.write("dist", c.dist[None, :])
            fs.write("R", c.R)
            fs.write("t", c.t[:, None])
            fs.endWriteStruct()
        fs.endWriteStruct()
    finally:
        fs.release()


# --- Pose2Sim / anipose TOML -------------------------------------------------------------------


def read_pose2sim_calibration(path: PathLike, image_sizes: ImageSizes | None = None) -> Rig:
    """Pose2Sim / anipose ``Calib.toml`` (see the module docstring)."""
    text = _read_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CalibrationError(path, f"cannot parse TOML ({exc})") from None
    cams = []
    for key, table in data.items():
        if key in _TOML_NON_CAMERA_TABLES or not isinstance(table, dict):
            continue
        label = str(table.get("name", key))
        for field in ("size", "matrix", "distortions", "rotation", "translation"):
            if field not in table:
                raise CalibrationError(path, "missing", label, field)
        if table.get("fisheye", False):
            raise CalibrationError(path, "the fisheye model is not supported", label, "fisheye")
        size = table["size"]
        if not isinstance(size, list) or len(size) != 2:
            raise CalibrationError(path, f"expected [width, height], got {size!r}", label, "size")
        try:
            rotation = np.asarray(table["rotation"], dtype=np.float64)
        except (TypeError, ValueError):
            rotation = None
        if rotation is not None and rotation.shape == (3,) and np.all(np.isfinite(rotation)):
            R = rotation_from_rodrigues(rotation)
        elif rotation is not None and rotation.shape == (3, 3):
            R = rotation
        else:
            raise CalibrationError(path, "expected a Rodrigues vector of 3 numbers (or a 3x3 "
                                         f"matrix), got {table['rotation']!r}", label, "rotation")
        cams.append(_build_camera(path, label, _TOML_FIELDS, name=label, K=table["matrix"],
                                  dist=table["distortions"], R=R, t=table["translation"],
                                  width=size[0], height=size[1]))
    return _check_rig(path, cams, _TOML_FIELDS, image_sizes)


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[ " + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k, ensure_ascii=False)


def write_pose2sim_calibration(rig: Rig, path: PathLike,
                               metadata: Mapping[str, object] | None = None) -> None:
    """Pose2Sim TOML: one ``[<name>]`` table per camera, then ``[metadata]`` (default
    ``adjusted = false``, ``error = 0.0`` as Pose2Sim writes). ``distortions`` has 4
    coefficients, or 5 when k3 != 0."""
    if metadata is None:
        metadata = {"adjusted": False, "error": 0.0}
    lines: list[str] = []
    for c in rig:
        dist = c.dist if c.dist[4] != 0 else c.dist[:4]
        lines += [
            f"[{_toml_key(c.name)}]",
            f"name = {_toml_value(c.name)}",
            f"size = {_toml_value([float(c.width), float(c.height)])}",
            f"matrix = {_toml_value(c.K.tolist())}",
            f"distortions = {_toml_value(dist.tolist())}",
            f"rotation = {_toml_value(rodrigues_from_rotation(c.R).tolist())}",
            f"translation = {_toml_value(c.t.tolist())}",
            "fisheye = false",
            "",
        ]
    if metadata:
        lines.append("[metadata]")
        lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in metadata.items()]
        lines.append("")
    Path(path).write_text("\n".join(lines), encoding="utf-8")


# --- dispatch ----------------------------------------------------------------------------------


def load_calibration(path: PathLike, image_sizes: ImageSizes | None = None) -> Rig:
    """Load any supported calibration, by extension: ``.json`` ours; ``.yaml``/``.yml`` ours
    or OpenCV FileStorage (detected by content: ``%YAML:`` header or ``!!opencv-matrix``);
    ``.xml`` OpenCV FileStorage; ``.toml`` Pose2Sim / anipose.

    image_sizes: optional expected (width, height) per camera, as a mapping by name or a
    sequence in file order (e.g. the sizes of the videos); a mismatch raises.
    Raises :class:`CalibrationError` naming the file, camera and field.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".json":
        return read_mocap_calibration(path, image_sizes)
    if suffix in (".yaml", ".yml"):
        if _is_opencv_yaml(_read_text(path)):
            return read_opencv_calibration(path, image_sizes)
        return read_mocap_calibration(path, image_sizes)
    if suffix == ".xml":
        return read_opencv_calibration(path, image_sizes)
    if suffix == ".toml":
        return read_pose2sim_calibration(path, image_sizes)
    raise CalibrationError(path, f"unknown calibration extension {suffix!r} (expected .json, "
                                 ".yaml, .yml, .xml or .toml)")


_WRITERS: dict[str, Callable[[Rig, PathLike], None]] = {
    "mocap": write_mocap_calibration,
    "opencv": write_opencv_calibration,
    "pose2sim": write_pose2sim_calibration,
}


def save_calibration(rig: Rig, path: PathLike, format: str | None = None) -> None:
    """Write ``rig`` to ``path``. format: "mocap", "opencv" or "pose2sim"; None picks by
    extension (.json/.yaml/.yml: mocap, .xml: opencv, .toml: pose2sim)."""
    if format is None:
        suffix = Path(path).suffix.lower()
        format = {".json": "mocap", ".yaml": "mocap", ".yml": "mocap", ".xml": "opencv",
                  ".toml": "pose2sim"}.get(suffix)
        if format is None:
            raise ValueError(f"{path}: cannot tell the calibration format from {suffix!r}")
    if format not in _WRITERS:
        raise ValueError(f"unknown calibration format {format!r}; one of {sorted(_WRITERS)}")
    _WRITERS[format](rig, path)
