"""Name maps: which joint of a motion-capture skeleton is which point of our body, in data.

A name map is a YAML file in ``mocap/clips/maps/`` (shipped with the package):

    name: bandai_namco
    description: ...
    unit: cm                  # the file's length unit: m, cm, mm, inch (or a label, then
    metres_per_unit: 0.01     #   metres_per_unit is required)
    up: y                     # the file's up axis: y or z
    recognise: [Hips, ...]    # a clip whose joints include all these is this skeleton
    joints:                   # clip joint -> a joint of the body or a landmark of
      Hips: mid_hip           #   mocap.body.catalogue; null: not used
      ...

To add a skeleton, drop such a file into ``mocap/clips/maps/`` (or pass a map loaded with
:func:`load_map` to :func:`mocap.clips.retarget.retarget`); see docs/clips.md.
When several maps recognise a clip, the one recognising the most joints wins.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

import yaml

_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254}


@dataclass(frozen=True)
class NameMap:
    """A skeleton's name map (see the module docstring). ``joints``: clip name -> our point
    name, only the mapped ones (the null entries left out)."""

    name: str
    description: str
    unit: str
    metres_per_unit: float
    up: str
    recognise: tuple[str, ...]
    joints: Mapping[str, str]
    source: str = ""

    def matches(self, names: Sequence[str]) -> bool:
        return set(self.recognise) <= set(names)


def load_map(path: str | Path) -> NameMap:
    """A :class:`NameMap` from a YAML file; errors name the file and the field."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise ValueError(f"name map {path}: cannot be read ({e})") from None
    if not isinstance(data, dict):
        raise ValueError(f"name map {path}: expected a mapping with name, unit, up, recognise, joints")
    missing = [k for k in ("name", "unit", "up", "recognise", "joints") if k not in data]
    if missing:
        raise ValueError(f"name map {path}: missing field(s) {', '.join(missing)}")
    unit = str(data["unit"])
    scale = data.get("metres_per_unit", _UNITS.get(unit))
    if scale is None or not float(scale) > 0:
        raise ValueError(f"name map {path}: unit {unit!r} is not one of {', '.join(_UNITS)}; "
                         "give metres_per_unit")
    if data["up"] not in ("y", "z"):
        raise ValueError(f"name map {path}: up={data['up']!r}, allowed y or z")
    joints = data["joints"] or {}
    if not isinstance(joints, dict) or not isinstance(data["recognise"], list) or not data["recognise"]:
        raise ValueError(f"name map {path}: joints must be a mapping and recognise a non-empty list")
    return NameMap(name=str(data["name"]), description=str(data.get("description", "")), unit=unit,
                   metres_per_unit=float(scale), up=str(data["up"]),
                   recognise=tuple(str(n) for n in data["recognise"]),
                   joints={str(k): str(v) for k, v in joints.items() if v is not None},
                   source=str(path))


@lru_cache(maxsize=1)
def shipped_maps() -> tuple[NameMap, ...]:
    """The maps in ``mocap/clips/maps/*.yaml``, sorted by name."""
    folder = resources.files("mocap.clips") / "maps"
    return tuple(sorted((load_map(Path(str(f))) for f in folder.iterdir() if f.name.endswith(".yaml")),
                        key=lambda m: m.name))


def detect_map(names: Sequence[str], maps: Sequence[NameMap] | None = None) -> NameMap | None:
    """The map that recognises a skeleton with these joint names (the one recognising the most
    joints when several do), or None."""
    hits = [m for m in (shipped_maps() if maps is None else maps) if m.matches(names)]
    return max(hits, key=lambda m: len(m.recognise)) if hits else None


def map_named(name: str) -> NameMap:
    for m in shipped_maps():
        if m.name == name:
            return m
    raise ValueError(f"no name map {name!r} (shipped: {', '.join(m.name for m in shipped_maps())})")
