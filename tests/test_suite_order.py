"""The suite runs its longest files first (tests/conftest.py, tests/file_durations.json): under
pytest-xdist a long file dealt last keeps one worker busy while the others idle."""

import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_the_files_run_longest_first_by_their_recorded_seconds():
    seconds = json.loads((REPO / "tests" / "file_durations.json").read_text())
    files = ["tests/test_layers.py", "tests/test_wheel.py", "tests/cli/test_rescore.py"]   # in neither order
    assert all(f in seconds for f in files)
    r = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                        *files], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    order = list(dict.fromkeys(line.split("::")[0] for line in r.stdout.splitlines() if "::" in line))
    assert order == sorted(files, key=lambda f: -seconds[f])
    # each file's tests stay together and in their own order
    ids = [line for line in r.stdout.splitlines() if "::" in line]
    assert [i.split("::")[0] for i in ids] == sorted((i.split("::")[0] for i in ids), key=order.index)
