"""The paper's robot as pinocchio loads it: Table 1 and the paper's start pose."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import CONFIG_DIR, PAPER_URDF

from bracing_core.chain_urdf import paper_4link_urdf


def test_committed_urdf_is_the_generated_one() -> None:
    assert PAPER_URDF.read_text() == paper_4link_urdf()


def test_table_1_as_loaded_by_pinocchio() -> None:
    model = pin.buildModelFromUrdf(str(PAPER_URDF))
    assert [model.names[j] for j in range(1, model.njoints)] == ["joint1", "joint2", "joint3", "joint4"]
    masses, radii = (1.0, 1.0, 0.5, 1.0), (0.03, 0.03, 0.01, 0.03)
    for j, (mass, radius) in enumerate(zip(masses, radii, strict=True), start=1):
        inertia = model.inertias[j]
        assert inertia.mass == pytest.approx(mass)
        np.testing.assert_allclose(inertia.lever, [0.0, 0.0, 0.25])  # centre of mass mid-link
        transverse = mass * (3 * radius**2 + 0.5**2) / 12
        np.testing.assert_allclose(np.diag(inertia.inertia), [transverse, transverse, mass * radius**2 / 2])
    np.testing.assert_allclose(model.damping, [2.0] * 4)
    assert (CONFIG_DIR / "paper_4link.yaml").is_file()


def test_start_pose_puts_the_elbow_on_the_floor() -> None:
    model = pin.buildModelFromUrdf(str(PAPER_URDF))
    data = model.createData()
    q = np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi
    pin.framesForwardKinematics(model, data, q)
    elbow = data.oMf[model.getFrameId("elbow")].translation
    hand = data.oMf[model.getFrameId("hand")].translation
    np.testing.assert_allclose(elbow, [0.0, 0.5878, 0.0], atol=5e-5)
    assert abs(elbow[2]) < 1e-15
    np.testing.assert_allclose(hand, [0.0, 1.0633, 0.6545], atol=5e-5)
