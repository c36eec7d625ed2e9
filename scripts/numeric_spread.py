"""The cross-CPU spread of the golden tests: runs the saved-reference computations of
tests/trackers/test_tracks_unchanged.py and tests/clips/test_fit.py::test_oracle_unchanged_by_the_refactor
in fresh processes under pinned numeric paths (numba's target CPU, OpenBLAS's kernel, numpy's and
OpenCV's SIMD dispatch) and prints each path's largest difference from the saved references.

    PYTHONPATH=$PWD .venv/bin/python scripts/numeric_spread.py [NAME ...] [--oracle-only]

A path is an environment the libraries read when they load (see PATHS); the differences are what
another CPU's kernels would give, measured on one machine. docs/cluster.md quotes the result.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_NPY_NO_AVX512 = ("AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL "
                  "AVX512_ICL AVX512_SPR AVX512FP16")
_CV_NO_AVX512 = "AVX512_SKX,AVX512_COMMON,AVX512_KNL,AVX512_KNM,AVX512_CNL,AVX512_CLX,AVX512_ICL"
#: name -> environment of that numeric path (on top of the caller's)
PATHS = {
    "host": {},
    "numba-generic": {"NUMBA_CPU_NAME": "generic"},
    "openblas-haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "openblas-sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge"},
    "openblas-prescott": {"OPENBLAS_CORETYPE": "Prescott"},
    "numpy-no-avx512": {"NPY_DISABLE_CPU_FEATURES": _NPY_NO_AVX512},
    "opencv-no-avx512": {"OPENCV_CPU_DISABLE": _CV_NO_AVX512},
    # an AVX2 machine (e.g. an AMD EPYC Zen 2/3): every library on its AVX2 path
    "avx2-machine": {"NUMBA_CPU_NAME": "haswell", "OPENBLAS_CORETYPE": "Haswell",
                     "NPY_DISABLE_CPU_FEATURES": _NPY_NO_AVX512, "OPENCV_CPU_DISABLE": _CV_NO_AVX512},
    # the oldest x86-64 paths
    "generic": {"NUMBA_CPU_NAME": "generic", "OPENBLAS_CORETYPE": "Prescott",
                "NPY_DISABLE_CPU_FEATURES": _NPY_NO_AVX512 + " AVX2 FMA3 F16C AVX SSE42 SSE41 POPCNT SSSE3",
                "OPENCV_CPU_DISABLE": _CV_NO_AVX512 + ",AVX2,FMA3,FP16,AVX,POPCNT,SSE4_2,SSE4_1,SSSE3"},
}

_CHILD = r"""
import json, sys
import numpy as np
from mocap.body import load_body_model
from tests.conftest import body_config
from tests.trackers import test_tracks_unchanged as tt
from tests.clips.test_fit import DATA, observed_difference_mm
from mocap.eval.mismatch import fit_oracle
body = load_body_model(body_config("paper22")["dofs"], name="paper22")
out = {}
saved = np.load(tt.SAVED)
for run, chi in (tt.tracks(body) if "--oracle-only" not in sys.argv else {}).items():
    out["track/" + run + "/rad"] = float(np.abs(chi - saved[run]).max())
    out["track/" + run + "/mm"] = tt.joint_difference_mm(body, chi, saved[run])
ref = np.load(DATA / "oracle_before_refactor.npz")
fit = fit_oracle(body, [str(n) for n in ref["names"]], ref["gt"], ref["valid"], "humaneva15", shape_frames=4)
out["oracle/alpha"] = float(np.abs(fit.alpha - ref["alpha"]).max())
out["oracle/chi_rad"] = float(np.abs(fit.chi - ref["chi"]).max())
out["oracle/observed_mm"] = observed_difference_mm(body, fit.alpha, fit.chi, ref)
out["oracle/raw_mm"] = abs(fit.metrics["raw_mm"] - float(ref["raw_mm"]))
print("RESULT " + json.dumps(out))
"""


def spread(name: str) -> dict[str, float]:
    """Largest |difference| from the saved references per computation, under path ``name``."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1",
           "PYTHONPATH": str(ROOT), **PATHS[name]}
    done = subprocess.run([sys.executable, "-c", _CHILD, *ARGS], cwd=ROOT, env=env, capture_output=True,
                          text=True, check=False)
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
    if done.returncode or not lines:
        raise SystemExit(f"path {name} failed:\n{done.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT "):])


ARGS = [a for a in sys.argv[1:] if a.startswith("--")]       # --oracle-only: skip the tracks

if __name__ == "__main__":
    for name in [a for a in sys.argv[1:] if not a.startswith("--")] or PATHS:
        print(name, json.dumps({k: f"{v:.2g}" for k, v in spread(name).items()}), flush=True)
