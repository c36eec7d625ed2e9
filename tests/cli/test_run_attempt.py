"""The failure handling shared by one-person and several-people runs (mocap/run_folder/attempt.py)."""

from __future__ import annotations

import pytest

from mocap.run_folder.attempt import DURING_WORK_NOTE, run_attempt


class Sink:
    def __init__(self):
        self.calls = []

    def finish(self, metrics, failed=False):
        self.calls.append((metrics, failed))


def test_failure_closes_the_recording_as_failed_and_marks_the_exception(tmp_path, capsys):
    (tmp_path / "previous_run").mkdir()
    sink = Sink()
    with pytest.raises(ValueError) as info, run_attempt(tmp_path, sink):
        raise ValueError("broken")
    assert sink.calls == [(None, True)]
    assert DURING_WORK_NOTE in info.value.__notes__
    err = capsys.readouterr().err
    assert f"{tmp_path}: not complete, no manifest.json written (ValueError)" in err
    assert "earlier complete run is kept in previous_run/" in err
    assert (tmp_path / "previous_run").is_dir()        # kept: this attempt did not complete


def test_os_errors_and_interrupts_are_not_marked_as_programming_errors(tmp_path):
    for exc in (OSError(28, "No space left on device"), KeyboardInterrupt()):
        sink = Sink()
        with pytest.raises(type(exc)) as info, run_attempt(tmp_path, sink):
            raise exc
        assert sink.calls == [(None, True)]
        assert DURING_WORK_NOTE not in getattr(info.value, "__notes__", ())


def test_success_drops_the_earlier_run(tmp_path):
    (tmp_path / "previous_run").mkdir()
    (tmp_path / "previous_run" / "metrics.json").write_text("{}")
    sink = Sink()
    with run_attempt(tmp_path, sink):
        pass
    assert sink.calls == []
    assert not (tmp_path / "previous_run").exists()
