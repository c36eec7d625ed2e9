"""The kernels built ahead of time (:mod:`mocap.kernel_cache`): the shipped list of argument types
names kernels that exist with types numba reads back to the same types, every kernel of the package
is in it, and :func:`~mocap.kernel_cache.warm` compiles exactly what is listed, skipping (not
failing on) entries that no longer fit."""

import importlib
import inspect
import json
import pkgutil
import re
from pathlib import Path

import numpy as np
import pytest

import mocap
from mocap import kernel_cache
from mocap.compiled import HAVE_NUMBA

pytestmark = pytest.mark.skipif(not HAVE_NUMBA, reason="numba is not installed")

LISTED = json.loads(kernel_cache.SIGNATURES.read_text())


def kernel_modules():
    """Every mocap module whose source defines a numba kernel."""
    root = Path(mocap.__file__).parent
    for info in pkgutil.walk_packages([str(root)], prefix="mocap."):
        path = root.joinpath(*info.name.split(".")[1:])
        source = path / "__init__.py" if info.ispkg else path.with_suffix(".py")
        if source.is_file() and "njit(" in source.read_text():
            yield info.name


def test_every_listed_signature_reads_back_as_numbas_own_types():
    for key, sigs in LISTED.items():
        for sig in sigs:
            assert repr(kernel_cache.parse_signature(sig)) == sig, key


def test_every_listed_kernel_exists_and_every_kernel_called_from_python_is_listed():
    found = {}
    for name in kernel_modules():
        for attr, kernel in kernel_cache._dispatchers(importlib.import_module(name)).items():
            found[f"{name}:{attr}"] = kernel
    assert len(found) > 40
    assert set(LISTED) <= set(found), sorted(set(LISTED) - set(found))
    # a kernel called by another kernel is compiled with it (numba compiles the callees of what it
    # compiles); every other one is listed (a new kernel: re-record the list, docs/results/speed.md
    # "Kernels compiled ahead")
    sources = {key: inspect.getsource(kernel.py_func) for key, kernel in found.items()}

    def called_by_a_kernel(key):
        attr = key.partition(":")[2]
        return any(re.search(rf"\b{attr}\(", src) for other, src in sources.items() if other != key)

    entry_points = {key for key in found if not called_by_a_kernel(key)}
    assert entry_points - set(LISTED) == set(), sorted(entry_points - set(LISTED))


def test_signature_reader_refuses_what_it_does_not_know():
    for text in ["int64", "(Record(a: float64), int64)", "(os, int64)", "(__import__, int64)",
                 "(Array(float64, 2, 'C', False, aligned=True) int64)"]:
        with pytest.raises(ValueError):
            kernel_cache.parse_signature(text)
    from numba.core import types
    assert kernel_cache.parse_signature("(float32, Array(int32, 1, 'A', True, aligned=True),)") == (
        types.float32, types.Array(types.int32, 1, "A", readonly=True))


def test_work_order_keeps_a_modules_kernels_together_largest_module_first():
    from mocap.energy import fused
    from mocap.trackers import apf

    entries = {"mocap.trackers.apf:b": ["x"], "mocap.energy.fused:a": ["x", "y"],
               "mocap.trackers.apf:a": ["x"], "mocap.no_such_module:f": ["x"]}
    assert Path(fused.__file__).stat().st_size > Path(apf.__file__).stat().st_size
    assert kernel_cache.work_order(entries) == [
        [("mocap.energy.fused:a", ["x", "y"])],
        [("mocap.trackers.apf:a", ["x"]), ("mocap.trackers.apf:b", ["x"])],
        [("mocap.no_such_module:f", ["x"])]]


def test_warm_compiles_the_listed_types_and_skips_stale_entries(tmp_path):
    from mocap.body import root_motion

    key = next(k for k in LISTED if k.startswith("mocap.body.root_motion:"))
    kernel = getattr(root_motion, key.partition(":")[2])
    listed = tmp_path / "signatures.json"
    listed.write_text(json.dumps({key: LISTED[key], "mocap.body.root_motion:no_such_kernel": ["(int64,)"],
                                  "os:system": ["(int64,)"], key + "_": ["(int64,)"]}))
    r = kernel_cache.warm(jobs=1, path=listed, stamps=tmp_path)   # in this process: its dispatcher holds them
    assert r["compiled"] == len(LISTED[key]) and not r["up_to_date"]
    assert {repr(s) for s in kernel.signatures} >= set(LISTED[key])
    assert len(r["skipped"]) == 3 and any("not a mocap module" in s for s in r["skipped"])
    again = kernel_cache.warm(jobs=1, path=listed, stamps=tmp_path)
    assert again["up_to_date"] and again["compiled"] == 0


def test_the_stamp_changes_with_the_list_the_cpu_and_the_sources(tmp_path, monkeypatch):
    listed = tmp_path / "signatures.json"
    listed.write_text("{}")
    key = kernel_cache.stamp_key(listed)
    assert kernel_cache.stamp_key(listed) == key
    monkeypatch.setenv("NUMBA_CPU_NAME", "generic")
    generic = kernel_cache.stamp_key(listed)
    assert generic != key
    listed.write_text('{"mocap.x:f": []}')
    assert kernel_cache.stamp_key(listed) not in (key, generic)
    monkeypatch.setattr(kernel_cache, "__file__", str(tmp_path / "pkg" / "kernel_cache.py"))
    (tmp_path / "pkg").mkdir()
    source = tmp_path / "pkg" / "a.py"
    source.write_text("x = 1\n")
    before = kernel_cache.stamp_key(listed)
    source.write_text("x = 22\n")
    assert kernel_cache.stamp_key(listed) != before


def test_a_call_after_warming_uses_the_kernel_built_ahead():
    """The call with the listed types runs the overload built ahead (no new one is compiled) and
    returns what the module's numpy path returns."""
    from mocap.body import root_motion

    key = next(k for k in LISTED if k.endswith(":_root_spread_nb"))
    kernel = getattr(root_motion, key.partition(":")[2])
    for sig in LISTED[key]:
        kernel.compile(kernel_cache.parse_signature(sig))
    built = list(kernel.signatures)
    xi = np.random.default_rng(0).normal(scale=0.3, size=(7, 6))
    root = np.array([0.0, 0.9, 0.1])
    compiled = root_motion.root_spread(xi, root, compiled=True)
    assert list(kernel.signatures) == built
    np.testing.assert_allclose(compiled, root_motion.root_spread(xi, root, compiled=False), atol=1e-12)
