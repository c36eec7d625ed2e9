"""The compiled kernels built ahead of time, on every core, into numba's cache.

Every numba kernel of the package is compiled with ``cache=True``: the first process that calls
one with given argument types compiles it (seconds each, about a minute for the whole package)
and writes the machine code beside the module (``__pycache__/*.nbi|nbc``); later processes load
it. Left to the first run, that minute lands on whoever runs first, and several processes that
start together (the test suite's workers, a sweep's jobs) each compile the same kernels at once.

:func:`warm` compiles them before that: the argument types every kernel is called with are listed
in :data:`SIGNATURES` (``kernel_signatures.json``, recorded from a run of the test suite with
``MOCAP_RECORD_KERNELS``, see :func:`record`), and ``jobs`` processes compile them a module at a
time (:func:`work_order`), so each is compiled once, on all cores at once. Kernels already in the
cache are only loaded. The machine code is the same as a first call would compile (same function,
same types, same CPU), so results do not change. Command line:
``python -m mocap.kernel_cache [--jobs N]`` (what ``scripts/setup_env.sh`` runs). A listed kernel
that no longer exists, or a type that no longer parses, is reported and skipped: the kernel is then
compiled at its first call, as without this.

The list is data: only kernels of the package's own ``mocap.*`` modules are looked up, and the
types are read by a fixed grammar (arrays of numba's scalar types, the scalars), never evaluated.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

#: the kernels' argument types: ``{"module:attribute": ["(type, type, ...)", ...]}``
SIGNATURES = Path(__file__).with_name("kernel_signatures.json")

_ARRAY = re.compile(r"Array\((\w+), (\d+), '([CFA])', (False|True), aligned=(True|False)\)")
_SCALAR = re.compile(r"[a-z]+\d*")


def _dispatchers(module) -> dict[str, object]:
    """The module-level numba kernels defined in ``module`` (attribute name -> dispatcher)."""
    from numba.core.registry import CPUDispatcher

    return {name: obj for name, obj in vars(module).items()
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == module.__name__}


def parse_signature(text: str) -> tuple:
    """``"(Array(float64, 2, 'C', False, aligned=True), int64)"`` -> numba argument types.

    Only C/F/A arrays of numba's scalar types and the scalars themselves: anything else raises
    :class:`ValueError` (the kernel is then left to its first call)."""
    from numba.core import types

    if not (text.startswith("(") and text.endswith(")")):
        raise ValueError(f"not an argument tuple: {text!r}")
    inner = text[1:-1].strip().rstrip(",")
    out, pos = [], 0
    while pos < len(inner):
        m = _ARRAY.match(inner, pos)
        if m:
            dtype, ndim, layout, readonly, aligned = m.groups()
            out.append(types.Array(_scalar(types, dtype), int(ndim), layout, readonly=readonly == "True",
                                   aligned=aligned == "True"))
        else:
            m = _SCALAR.match(inner, pos)
            if not m:
                raise ValueError(f"unsupported type at {inner[pos:pos + 40]!r}")
            out.append(_scalar(types, m.group(0)))
        pos = m.end()
        if inner.startswith(", ", pos):
            pos += 2
        elif pos < len(inner):
            raise ValueError(f"unexpected {inner[pos:pos + 40]!r}")
    return tuple(out)


def _scalar(types, name: str):
    t = getattr(types, name, None)
    if not isinstance(t, (types.Integer, types.Float, types.Boolean, types.Complex)):
        raise ValueError(f"not a numba scalar type: {name!r}")
    return t


def _compile(entries: list[tuple[str, list[str]]]) -> dict:
    """One worker: compile (or load from the cache) each ``("module:attribute", signatures)``."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    done, skipped, start = 0, [], time.perf_counter()
    for key, sigs in entries:
        module_name, _, attr = key.partition(":")
        if not module_name.startswith("mocap."):
            skipped.append(f"{key}: not a mocap module")
            continue
        try:
            kernel = _dispatchers(importlib.import_module(module_name)).get(attr)
        except ImportError as e:
            skipped.append(f"{key}: {e}")
            continue
        if kernel is None:
            skipped.append(f"{key}: no such kernel")
            continue
        for sig in sigs:
            try:
                kernel.compile(parse_signature(sig))
                done += 1
            except Exception as e:          # noqa: BLE001 - a stale entry: left to its first call
                skipped.append(f"{key}{sig[:60]}: {type(e).__name__}: {str(e).splitlines()[0][:120]}")
    return {"compiled": done, "skipped": skipped, "seconds": time.perf_counter() - start}


def work_order(entries: dict[str, list[str]]) -> list[list[tuple[str, list[str]]]]:
    """The kernels grouped by module (a module's kernels share its import and, often, callees), the
    largest module source first: handed out one group at a time to whichever worker is free, the
    longest compiles start first and the short ones fill in (the module's size stands in for its
    compile time: fused.py's kernels take ~25 of the ~85 CPU s)."""
    import importlib.util

    by_module: dict[str, list[tuple[str, list[str]]]] = {}
    for key, sigs in sorted(entries.items()):
        by_module.setdefault(key.partition(":")[0], []).append((key, sigs))

    def size(module: str) -> int:
        try:
            spec = importlib.util.find_spec(module) if module.startswith("mocap.") else None
        except (ImportError, ValueError):
            return 0
        origin = Path(spec.origin) if spec and spec.origin else None
        return origin.stat().st_size if origin and origin.is_file() else 0

    return [by_module[m] for m in sorted(by_module, key=lambda m: (-size(m), m))]


def stamp_key(path: Path = SIGNATURES) -> str:
    """What the built kernels depend on, hashed: the list, every source file of the package (size and
    modification time: numba's own cache test, here over all files since a kernel's callees may live
    in another), numba's version, the CPU numba compiles for (``NUMBA_CPU_NAME``) and the machine."""
    import hashlib
    import importlib.metadata
    import platform

    h = hashlib.sha1(path.read_bytes() if path.is_file() else b"")
    try:
        h.update(importlib.metadata.version("numba").encode())
    except importlib.metadata.PackageNotFoundError:
        h.update(b"no numba")
    h.update(f"{os.environ.get('NUMBA_CPU_NAME', '')}|{platform.machine()}|{sys.version_info[:2]}".encode())
    package = Path(__file__).parent
    for source in sorted(package.rglob("*.py")):
        st = source.stat()
        h.update(f"{source.relative_to(package)}:{st.st_size}:{st.st_mtime_ns}".encode())
    return h.hexdigest()[:16]


def warm(jobs: int | None = None, path: Path = SIGNATURES, stamps: Path | None = None) -> dict:
    """Compile every listed kernel into numba's cache on ``jobs`` processes (default: every core).

    Returns ``{"compiled": n, "skipped": [...], "seconds": wall, "up_to_date": bool}``; a no-op
    without numba, and when ``stamps`` (default: the package's ``__pycache__``, where numba's cache
    is) holds the stamp of an earlier warm with the same :func:`stamp_key`."""
    stamps = Path(__file__).with_name("__pycache__") if stamps is None else stamps
    stamp = stamps / f"kernels-{stamp_key(path)}.stamp"
    if stamp.is_file():
        return {"compiled": 0, "skipped": [], "seconds": 0.0, "up_to_date": True}
    from mocap.compiled import HAVE_NUMBA

    if not HAVE_NUMBA or not path.is_file():
        return {"compiled": 0, "skipped": [], "seconds": 0.0, "up_to_date": False}
    entries = json.loads(path.read_text())
    if not isinstance(entries, dict):
        raise ValueError(f"{path}: expected a mapping of kernels to signatures")
    start = time.perf_counter()
    groups = work_order(entries)
    jobs = min(jobs or os.cpu_count() or 1, len(groups))
    if jobs <= 1:
        results = [_compile([e for g in groups for e in g])]
    else:
        with ProcessPoolExecutor(jobs) as pool:
            results = list(pool.map(_compile, groups, chunksize=1))
    try:
        stamps.mkdir(parents=True, exist_ok=True)
        stamp.touch()                   # (one per key: the generic CPU's beside the native one's)
    except OSError:                     # a read-only install: warmed again next time, no harm
        pass
    return {"compiled": sum(r["compiled"] for r in results),
            "skipped": [s for r in results for s in r["skipped"]],
            "seconds": time.perf_counter() - start, "up_to_date": False}


def record(path: str | Path) -> dict[str, list[str]]:
    """The argument types every loaded mocap kernel has been compiled for in this process,
    written to ``path`` (JSON). The test suite calls it at its end when ``MOCAP_RECORD_KERNELS``
    names a file stem (one file per worker); :func:`merge` joins them into :data:`SIGNATURES`."""
    out: dict[str, list[str]] = {}
    for name, module in sorted(sys.modules.items()):
        if not name.startswith("mocap.") or module is None:
            continue
        for attr, kernel in _dispatchers(module).items():
            sigs = sorted(repr(tuple(s)) for s in kernel.signatures)
            if sigs:
                out[f"{name}:{attr}"] = sigs
    Path(path).write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    return out


def merge(paths: list[Path], out: Path = SIGNATURES) -> dict[str, list[str]]:
    """Several :func:`record` files joined (a kernel's signatures united), written to ``out``."""
    merged: dict[str, set[str]] = {}
    for p in paths:
        for key, sigs in json.loads(Path(p).read_text()).items():
            merged.setdefault(key, set()).update(sigs)
    result = {k: sorted(v) for k, v in sorted(merged.items())}
    out.write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m mocap.kernel_cache", description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=None, help="processes (default: every core)")
    ap.add_argument("--merge", nargs="+", type=Path, metavar="RECORD",
                    help=f"join record files (MOCAP_RECORD_KERNELS) into {SIGNATURES.name} instead")
    args = ap.parse_args(argv)
    if args.merge:
        result = merge(args.merge)
        count = sum(map(len, result.values()))
        print(f"[kernels] {count} signatures of {len(result)} kernels -> {SIGNATURES}")
        return 0
    if args.jobs is not None and args.jobs < 1:
        ap.error(f"--jobs must be >= 1, got {args.jobs}")
    r = warm(args.jobs)
    if r["up_to_date"]:
        return 0
    print(f"[kernels] {r['compiled']} compiled or loaded in {r['seconds']:.1f} s"
          + (f"; {len(r['skipped'])} skipped (compiled at first call):" if r["skipped"] else ""))
    for s in r["skipped"]:
        print(f"  {s}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
