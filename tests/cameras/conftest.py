"""Fixtures for the camera tests."""

from __future__ import annotations

import numpy as np
import pytest

from mocap.cameras import Rig

from .helpers import random_rig


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture
def rig() -> Rig:
    return random_rig(7)
