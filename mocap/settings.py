"""Settings as frozen dataclasses, built from plain mappings with one-line errors.

A tracker's settings are one frozen dataclass (:mod:`mocap.trackers.tracker_settings`), the
only place its defaults are written; nested settings are nested dataclasses. A mapping (a
config node, keyword arguments) becomes settings through :func:`settings_from_mapping` or,
over settings already made (a preset), :func:`with_overrides`: nested mappings build nested
settings, lists become tuples, and an unknown key or an out-of-range value raises a one-line
:class:`ValueError` naming the dotted key (with the allowed keys, or the allowed range).
Range checks live in each dataclass's ``__post_init__`` (:func:`check`).
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping
from collections.abc import Sequence as Sequence_
from typing import Any, TypeVar

T = TypeVar("T")


class SettingError(ValueError):
    """An out-of-range setting: ``key`` (dotted), its ``value`` and what is ``allowed``."""

    def __init__(self, key: str, value: Any, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"setting {key} = {value!r} is out of range (allowed: {allowed})")


def check(settings: Any, name: str, ok: bool, allowed: str) -> None:
    """Raise :class:`SettingError` for field ``name`` of ``settings`` unless ``ok``."""
    if not ok:
        raise SettingError(name, getattr(settings, name), allowed)


def plain(value: Any) -> Any:
    """``value`` with mappings as dicts and sequences (not strings) as tuples, recursively
    (config containers such as OmegaConf's become plain Python)."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, Sequence_) and not isinstance(value, str | bytes):
        return tuple(plain(v) for v in value)
    return value


def _kind_error(key: str, default: Any, value: Any) -> str | None:
    """Why ``value`` cannot replace ``default`` (None: it can): a bool, a number, a string
    and a tuple stay what they are."""
    if default is None or value is None and not isinstance(default, bool):
        return None
    if isinstance(default, bool):
        return None if isinstance(value, bool) else "true or false"
    if isinstance(default, int | float):
        if isinstance(value, bool) or not isinstance(value, int | float):
            return "a number"
        if isinstance(default, int) and not isinstance(value, int) and not float(value).is_integer():
            return "an integer"
        return None
    if isinstance(default, tuple) and not isinstance(value, tuple):
        return f"a list of {len(default)}" if default else "a list"
    if isinstance(default, tuple) and default and all(isinstance(v, int | float) for v in default) \
            and len(value) != len(default):
        return f"a list of {len(default)} numbers"
    return None


def with_overrides(base: T, overrides: Mapping | None, prefix: str = "") -> T:
    """``base`` (a settings dataclass) with the keys of ``overrides`` replaced; nested
    mappings update nested settings key by key. ``prefix``: the dotted path of ``base`` in
    error messages."""
    if not overrides:
        return base
    fields = {f.name: f for f in dataclasses.fields(base) if f.init}
    changes = {}
    for key, value in overrides.items():
        dotted = f"{prefix}{key}"
        if key not in fields:
            close = difflib.get_close_matches(str(key), fields, n=3)
            hint = f"did you mean {', '.join(f'{prefix}{c}' for c in close)}? " if close else ""
            raise ValueError(f"unknown setting {dotted!r} ({type(base).__name__}); {hint}"
                             f"allowed: {', '.join(fields)}")
        current = getattr(base, key)
        if dataclasses.is_dataclass(current) and not isinstance(current, type):
            if dataclasses.is_dataclass(value) and not isinstance(value, type):
                changes[key] = value
                continue
            if not isinstance(value, Mapping):
                raise ValueError(f"setting {dotted} = {value!r} must be a mapping of the settings "
                                 f"{type(current).__name__}")
            changes[key] = with_overrides(current, value, f"{dotted}.")
            continue
        value = plain(value)
        kind = _kind_error(dotted, current, value)
        if kind:
            raise ValueError(f"setting {dotted} = {value!r} must be {kind} (default {current!r})")
        changes[key] = value
    try:
        return dataclasses.replace(base, **changes)
    except SettingError as e:
        raise SettingError(f"{prefix}{e.key}", e.value, e.allowed) from None
    except (TypeError, ValueError) as e:
        if prefix:
            raise ValueError(f"settings {prefix[:-1]}: {e}") from None
        raise


def settings_from_mapping(cls: type[T], mapping: Mapping | None = None) -> T:
    """Settings ``cls`` (a frozen dataclass whose fields all have defaults) from a plain
    mapping of the keys that differ from its defaults (see the module docstring)."""
    return with_overrides(cls(), mapping)


def settings_to_mapping(settings: Any) -> dict:
    """The settings as a plain tree (nested dicts, tuples as lists), e.g. a config's
    defaults."""
    out = {}
    for f in dataclasses.fields(settings):
        v = getattr(settings, f.name)
        if dataclasses.is_dataclass(v):
            out[f.name] = settings_to_mapping(v)
        else:
            out[f.name] = _listed(v)
    return out


def _listed(v: Any) -> Any:
    if isinstance(v, tuple | list):
        return [_listed(x) for x in v]
    if isinstance(v, Mapping):
        return {k: _listed(x) for k, x in v.items()}
    return v


def fields_of(settings: Any, cls: type[T], skip: tuple[str, ...] = ()) -> dict:
    """The values of ``settings`` for the init fields of ``cls`` (e.g. the keyword arguments
    of the object it configures)."""
    return {f.name: getattr(settings, f.name) for f in dataclasses.fields(cls)
            if f.init and f.name not in skip}
