"""The one error of calibration input: what is wrong, with which camera, and what to do."""

from __future__ import annotations


class CalibrationInputError(ValueError):
    """Bad calibration input, found before any file is written. ``camera``: the camera at
    fault ("" when none in particular); the message says what to do."""

    def __init__(self, camera: str, message: str):
        super().__init__(f"camera {camera!r}: {message}" if camera else message)
        self.camera = camera
