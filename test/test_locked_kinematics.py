"""One kinematics: /tf, markers and the animation pose the robot the simulator simulated, locked joints too.

The simulator publishes on ``robot_description`` the URDF as simulated (``simulated_urdf``: a
locked joint is a fixed joint at its locked position), and ``bracing_core.kinematics.LinkPoses`` is the core's
``RobotModel`` of that text; a locked joint is in no JointState, yet every link is where the
simulator's ``contacts`` put its frames.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from ros_helpers import REPO_ROOT, pair_argv, run
from rosbags.highlevel import AnyReader

from bracing_analysis.animation import ArmAnimation, nearest
from bracing_analysis.bag import read_series
from bracing_core.kinematics import LinkPoses
from bracing_core.model import ModelError, RobotModel, simulated_urdf

MOBILE_YAML = REPO_ROOT / "config" / "mobile_8joint.yaml"
MOBILE_URDF = REPO_ROOT / "config" / "mobile_8joint.urdf"
BASE_AT = 0.25  # [m]: the base locked off its zero, so a pose that ignores the lock is 0.25 m off
LOCKED = ("--set", "robot.locked_joints=[base_joint]", "--set", f"robot.locked_positions=[{BASE_AT}]")
DURATION = 0.05  # [s]: 51 states
TOLERANCE_M = 1e-9


def _joints(urdf: str) -> dict[str, str]:
    return {j.get("name", ""): j.get("type", "") for j in ET.fromstring(urdf).findall("joint")}


# --------------------------------------------------------------------------- in process, no ROS


@pytest.mark.parametrize(("locked", "at"), [(("base_joint",), (BASE_AT,)), (("base_joint", "joint3"), (BASE_AT, 0.7))])
def test_link_poses_of_the_published_urdf_are_the_reduced_models(
    locked: tuple[str, ...], at: tuple[float, ...]
) -> None:
    """LinkPoses of the published text, fed the moving joints only, places every link (and the
    contact frames) where the core's reduced model does: the model the engine steps."""
    text = MOBILE_URDF.read_text(encoding="utf-8")
    reduced = RobotModel.from_urdf(MOBILE_URDF, locked_joints=locked, locked_positions=at)
    published = simulated_urdf(text, locked, at)
    assert reduced.description() == published
    joints = _joints(published)
    assert all(joints[name] == "fixed" for name in locked)
    assert {n: t for n, t in joints.items() if n not in locked} == {
        n: t for n, t in _joints(text).items() if n not in locked
    }
    poses = LinkPoses(published)
    assert poses.robot.joint_names == reduced.joint_names  # what a JointState names
    q = np.linspace(-0.9, 1.1, reduced.nv)
    pin.framesForwardKinematics(reduced.model, reduced.data, q)
    poses.update(poses.configuration(reduced.joint_names, q))
    rows = poses.xyzquat(poses.body_ids)
    for name, row in zip(poses.body_names, rows, strict=True):
        expected = reduced.data.oMf[reduced.frame_id(name)]
        np.testing.assert_allclose(row[:3], expected.translation, rtol=0, atol=1e-12, err_msg=name)
        rotation = pin.Quaternion(row[6], *row[3:6]).toRotationMatrix()
        np.testing.assert_allclose(rotation, expected.rotation, rtol=0, atol=1e-12, err_msg=name)
    # The symptom: the locked base's cart is BASE_AT along y, fixed to the world.
    assert "cart" in poses.static_names
    cart = poses.xyzquat([poses.model.getFrameId("cart")])[0]
    np.testing.assert_allclose(cart[:3], [0.0, BASE_AT, 0.0], atol=1e-15)


def test_nothing_locked_publishes_the_urdf_as_loaded_and_bad_locks_are_refused() -> None:
    text = MOBILE_URDF.read_text(encoding="utf-8")
    assert simulated_urdf(text) is text
    assert RobotModel.from_urdf(MOBILE_URDF).description() == text
    with pytest.raises(ModelError, match=r"'wheel' is not a joint"):
        simulated_urdf(text, ["wheel"], [0.0])
    with pytest.raises(ModelError, match=r"'hand_joint' is not a joint"):  # fixed already: no joint to lock
        simulated_urdf(text, ["hand_joint"], [0.0])


# --------------------------------------------------------------------------- a real run


def _read(bag: Path, topics: set[str]) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {topic: [] for topic in topics}
    with AnyReader([bag]) as reader:
        wanted = [c for c in reader.connections if c.topic in topics]
        for connection, _, raw in reader.messages(connections=wanted):
            out[connection.topic].append(reader.deserialize(raw, connection.msgtype))
    return out


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


@pytest.fixture(scope="module")
def locked_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """mobile_8joint with its base locked at BASE_AT (the issue's command), a short bracing-pair run."""
    out = tmp_path_factory.mktemp("locked") / "run"
    done = run(pair_argv(out, "--duration", str(DURATION), *LOCKED, config=MOBILE_YAML), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def test_tf_puts_every_contact_frame_where_the_simulator_reports_it(locked_run: Path) -> None:
    bag = locked_run / "bag"
    got = _read(bag, {"/robot_description", "/joint_states", "/contacts", "/tf", "/tf_static"})
    (description,) = got["/robot_description"]
    assert _joints(description.data)["base_joint"] == "fixed"
    assert all("base_joint" not in m.name for m in got["/joint_states"])
    (static,) = got["/tf_static"]
    fixed = {t.child_frame_id: t.transform.translation for t in static.transforms}
    assert (fixed["cart"].x, fixed["cart"].y, fixed["cart"].z) == pytest.approx((0.0, BASE_AT, 0.0), abs=1e-15)
    tf = {_ns(m.transforms[0].header.stamp): m for m in got["/tf"]}
    assert len(tf) == len(got["/joint_states"]) == round(DURATION / 1e-3) + 1
    checked = 0
    worst = 0.0
    for message in got["/contacts"]:
        links = {t.child_frame_id: t.transform.translation for t in tf[_ns(message.header.stamp)].transforms}
        links.update(fixed)
        for contact in message.contacts:
            at = links[contact.frame]
            off = np.subtract((at.x, at.y, at.z), (contact.position.x, contact.position.y, contact.position.z))
            worst = max(worst, float(np.max(np.abs(off))))
            checked += 1
    assert checked >= 2 * len(got["/contacts"])  # both elbows (and the collision frames) every state
    assert worst < TOLERANCE_M, f"/tf is {worst:.3g} m off the simulator's contact positions"


def test_the_animation_draws_the_simulated_robot(locked_run: Path) -> None:
    """The animation's link positions at a contact's time: where the simulator put that contact."""
    series = read_series(locked_run / "bag")
    animation = ArmAnimation(series, interval_s=0.01)
    row = animation.poses.body_names.index("elbow1")
    elbow = series.contacts["elbow1"]
    state = series.joint_t[nearest(series.joint_t, animation.times)[-1]]
    k = int(np.argmin(np.abs(elbow.t - state)))
    assert elbow.t[k] == pytest.approx(state, abs=1e-9)  # the contacts of the drawn state
    np.testing.assert_allclose(animation.links[-1, row], elbow.position[k], rtol=0, atol=TOLERANCE_M)
