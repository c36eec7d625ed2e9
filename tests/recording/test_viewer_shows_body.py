"""The recording as a person sees it: the real Rerun viewer, headless (xvfb + Mesa's Vulkan
software rasteriser, installed by scripts/setup_env.sh), takes a screenshot of a short run's
recording; the estimated body (orange, ``BODY_RGB``) must be drawn in the 3D view.

Control: the same recording with the mesh entity dropped (``rerun rrd filter``) shows no
body-coloured pixels, so the colour test measures the mesh and nothing else. Recordings
written before the fix (static zero vertex positions shadowing the per-frame ones) give 0
body pixels here.
"""

import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

RERUN = Path(sys.executable).with_name("rerun")
VULKAN_ICDS = [Path("/usr/share/vulkan/icd.d"), Path("/etc/vulkan/icd.d")]

needs_viewer = pytest.mark.skipif(
    shutil.which("xvfb-run") is None or not any(d.is_dir() and any(d.glob("*.json")) for d in VULKAN_ICDS),
    reason="xvfb-run or a Vulkan driver is missing (scripts/setup_env.sh installs xvfb, "
           "mesa-vulkan-drivers, libvulkan1)")


def screenshot(rrd: Path, png: Path) -> np.ndarray:
    r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1920x1200x24", str(RERUN), str(rrd),
                        "--screenshot-to", str(png), "--window-size", "1280x800", "--renderer", "vulkan"],
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0 and png.is_file(), r.stderr[-2000:]
    return cv2.imread(str(png))[..., ::-1]


def body_pixels(rgb: np.ndarray) -> int:
    """Orange pixels (the mesh colour, shaded) in the 3D view: the blueprint's top-left panel."""
    H, W, _ = rgb.shape
    v = rgb[int(0.05 * H):int(0.6 * H), :int(0.6 * W)].astype(int)
    r, g, b = v[..., 0], v[..., 1], v[..., 2]
    return int(((r > 150) & (g > 60) & (g < 160) & (b < 90) & (r - g > 60)).sum())


@pytest.mark.slow
@needs_viewer
def test_viewer_draws_the_body_mesh(short_run, tmp_path):
    rrd = short_run / "recording.rrd"
    no_mesh = tmp_path / "no_mesh.rrd"
    f = subprocess.run([str(RERUN), "rrd", "filter", "--drop-entity", "/world/body/estimate", str(rrd),
                        "-o", str(no_mesh)], capture_output=True, text=True, timeout=120)
    assert f.returncode == 0, f.stderr
    with_body = body_pixels(screenshot(rrd, tmp_path / "shot.png"))
    without = body_pixels(screenshot(no_mesh, tmp_path / "shot_no_mesh.png"))
    assert without < 200, without           # nothing else in the 3D view is body-coloured
    assert with_body > 3000, with_body      # measured: ~11k pixels at 1280x800 (HiDPI 2x)
