"""The split of the motion-capture clips' motion types (``mocap/clips/split.yaml``, shipped with
the package): the types a pose prior may learn from and those held out for testing, and the
leak check that keeps a held-out type out of a training set."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import yaml


@dataclass(frozen=True)
class MotionSplit:
    """The motion types a prior may learn from (``train``) and those it must never see."""

    train: tuple[str, ...]
    held_out: tuple[str, ...]
    dataset: str = ""


def read_split(path: str | Path | None = None) -> MotionSplit:
    """The motion-type split (``mocap/clips/split.yaml`` unless ``path`` names another)."""
    path = Path(path) if path is not None else Path(__file__).with_name("split.yaml")
    d = yaml.safe_load(path.read_text())
    try:
        split = MotionSplit(tuple(d["train"]), tuple(d["held_out"]), str(d.get("dataset", "")))
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{path}: a split needs the lists 'train' and 'held_out' ({exc})") from exc
    both = sorted(set(split.train) & set(split.held_out))
    if both:
        raise ValueError(f"{path}: motion types in both train and held_out: {', '.join(both)}")
    return split


def check_training_types(types: tuple[str, ...] | list[str], split: MotionSplit) -> None:
    """The leak check: raise if a training motion type is held out (or not a train type)."""
    leak = sorted(set(types) & set(split.held_out))
    if leak:
        raise ValueError(f"motion types {', '.join(leak)} are held out by the split (held_out: "
                         f"{', '.join(split.held_out)}): they must never enter the prior's training set")
    unknown = sorted(set(types) - set(split.train))
    if unknown:
        raise ValueError(f"motion types {', '.join(unknown)} are not train types of the split "
                         f"(train: {', '.join(split.train)})")
