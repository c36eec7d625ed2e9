"""Shared fixtures: the shipped body model in both DOF configurations."""

from __future__ import annotations

from pathlib import Path

import pytest

from mocap.body import BodyModel, load_body_model

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


def body_config(name: str) -> dict:
    """The body preset (DOF list, name, dtype) shipped with the package."""
    from mocap import presets

    return presets.read("body", name)


@pytest.fixture(scope="session")
def body() -> BodyModel:
    """The paper's 22-DOF body, float32."""
    return load_body_model(body_config("paper22")["dofs"], name="paper22")


@pytest.fixture(scope="session")
def body64() -> BodyModel:
    return load_body_model(body_config("paper22")["dofs"], dtype="float64", name="paper22")


@pytest.fixture(scope="session")
def body_full() -> BodyModel:
    return load_body_model(body_config("full")["dofs"], dtype="float64", name="full")
