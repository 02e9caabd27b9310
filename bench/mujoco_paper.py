"""MuJoCo reference: the paper's 4-link bracing arm, stepped from Python.

Builds, as an MJCF string, a MuJoCo model equivalent to ``config/paper_4link.urdf``
(config/paper_4link.yaml): planar chain of four hinges about world x, links of 0.5 m along
local +z with the URDF's masses and inertias (solid cylinders, centre of mass
mid-link), joint damping D + D_m = 2.0 + 0.1 * 3^2 = 2.9, armature J_m = I_m k^2 =
0.000164 * 9, gravity -z 9.81, RK4, 1 ms. A small sphere at the elbow (tip of link 2)
rests on the floor with friction 0.1. To make the contact an exact point-on-plane
constraint for the elbow point itself, the sphere is centred at the elbow and the
collision plane is lowered by the sphere radius: the sphere touches the plane exactly
when the elbow point is at z = 0.

``mujoco_steps_per_s`` times ``mujoco.mj_step`` in a Python loop with a fresh
``data.qfrc_applied`` write before every step, so the number is comparable to a
Python-driven engine that takes one input per step. The constant input is the
gravity compensation at the initial pose plus J_elbow^T (0, 0, -10 N), i.e. the
elbow is pressed on the floor with the paper's desired force, so the contact stays
active during the whole timing.

Dependency: ``mujoco`` (requirements.lock, also bracing-pair --engine mujoco's).
"""

from __future__ import annotations

import math
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np

DT = 0.001
LINK_LENGTH = 0.5
MASSES = (1.0, 1.0, 0.5, 1.0)
RADII = (0.03, 0.03, 0.01, 0.03)
DAMPING = 2.0 + 0.1 * 3**2  # D + d_m k^2
ARMATURE = 0.000164 * 3**2  # I_m k^2
MU = 0.1
Q0 = tuple(c * math.pi for c in (-0.2, -0.6, 0.8, -0.4))
ELBOW_SPHERE_RADIUS = 0.005
PRESS_FORCE_N = 10.0  # f_nd of the paper
# The pose held by a constant input is an unstable equilibrium (links 3-4 stand up
# like an inverted pendulum): numerical residue grows ~e^(2t) and the arm falls off
# the floor after ~7 s. Timed runs therefore restart from q0 every SEGMENT_STEPS
# steps (restart outside the clock), so the elbow contact is active in every timed step.
SEGMENT_STEPS = 4000


def _cylinder_inertia(mass: float, radius: float, length: float) -> tuple[float, float, float]:
    """(ixx, iyy, izz) of a solid cylinder along z about its centre (same as the URDF)."""
    i_perp = mass * (3.0 * radius**2 + length**2) / 12.0
    return i_perp, i_perp, 0.5 * mass * radius**2


def paper_mjcf() -> str:
    """The MJCF string of the paper's 4-link arm with the elbow sphere and the floor."""
    half = LINK_LENGTH / 2.0
    body_open: list[str] = []
    for idx, (mass, radius) in enumerate(zip(MASSES, RADII, strict=True), start=1):
        ixx, iyy, izz = _cylinder_inertia(mass, radius, LINK_LENGTH)
        pos = "0 0 0" if idx == 1 else f"0 0 {LINK_LENGTH!r}"
        extra = ""
        if idx == 2:
            extra = (
                f'<site name="elbow" pos="0 0 {LINK_LENGTH!r}"/>'
                f'<geom name="elbow_ball" type="sphere" size="{ELBOW_SPHERE_RADIUS!r}" '
                f'pos="0 0 {LINK_LENGTH!r}" contype="1" conaffinity="0" condim="3" '
                f'friction="{MU!r} 0 0" mass="0"/>'
            )
        if idx == 4:
            extra = f'<site name="hand" pos="0 0 {LINK_LENGTH!r}"/>'
        body_open.append(
            f'<body name="link{idx}" pos="{pos}">'
            f'<joint name="joint{idx}" type="hinge" axis="1 0 0" pos="0 0 0"/>'
            f'<inertial pos="0 0 {half!r}" mass="{mass!r}" '
            f'diaginertia="{ixx!r} {iyy!r} {izz!r}"/>'
            f'<geom type="cylinder" size="{radius!r} {half!r}" pos="0 0 {half!r}" '
            f'contype="0" conaffinity="0" mass="0"/>'
            f"{extra}"
        )
    chain = "".join(body_open) + "</body>" * len(MASSES)
    return f"""
<mujoco model="paper_4link">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{DT!r}" integrator="RK4" gravity="0 0 -9.81"/>
  <default>
    <joint damping="{DAMPING!r}" armature="{ARMATURE!r}" limited="false"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" pos="0 0 {-ELBOW_SPHERE_RADIUS!r}"
          contype="0" conaffinity="1" condim="3" friction="{MU!r} 0 0"/>
    {chain}
  </worldbody>
</mujoco>
"""


def build() -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Compiled model and data at the initial pose (forward kinematics done)."""
    model = mujoco.MjModel.from_xml_string(paper_mjcf())
    data = mujoco.MjData(model)
    reset(model, data)
    return model, data


def reset(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    mujoco.mj_resetData(model, data)
    data.qpos[:] = Q0
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)


def constant_input(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Gravity compensation at q0 plus J_elbow^T pressing the elbow down with 10 N."""
    reset(model, data)
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "elbow")
    mujoco.mj_jacSite(model, data, jacp, jacr, site)
    return data.qfrc_bias.copy() + jacp.T @ np.array([0.0, 0.0, -PRESS_FORCE_N])


def sanity_check(n_steps: int = 1000) -> dict:
    """Not a timing: initial elbow/hand positions, then contact and elbow after stepping."""
    model, data = build()
    elbow = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "elbow")
    hand = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "hand")
    elbow0 = data.site_xpos[elbow].copy()
    hand0 = data.site_xpos[hand].copy()
    tau = constant_input(model, data)
    min_ncon = model.nv
    for _ in range(n_steps):
        data.qfrc_applied[:] = tau
        mujoco.mj_step(model, data)
        min_ncon = min(min_ncon, int(data.ncon))
    normal = np.zeros(6)
    if data.ncon:
        mujoco.mj_contactForce(model, data, 0, normal)
    out = {
        "elbow0_yz": [float(elbow0[1]), float(elbow0[2])],
        "hand0_yz": [float(hand0[1]), float(hand0[2])],
        "elbow_yz_after": [
            float(data.site_xpos[elbow][1]),
            float(data.site_xpos[elbow][2]),
        ],
        "hand_yz_after": [
            float(data.site_xpos[hand][1]),
            float(data.site_xpos[hand][2]),
        ],
        "min_contacts_during_run": min_ncon,
        "normal_force_after_n": float(normal[0]),
        "nv": int(model.nv),
        "armature": float(model.dof_armature[0]),
        "damping": float(model.dof_damping[0]),
        "body_mass": [float(v) for v in model.body_mass[1:]],
        "body_inertia_link3": [float(v) for v in model.body_inertia[3]],
    }
    ok = (
        abs(elbow0[2]) < 1e-9
        and abs(elbow0[1] - 0.5878) < 1e-4
        and abs(hand0[1] - 1.0633) < 1e-4
        and abs(hand0[2] - 0.6545) < 1e-4
        and min_ncon >= 1
        and abs(data.site_xpos[elbow][2]) < 5e-3
    )
    out.update(_compare_with_pinocchio(model))
    ok = ok and out.get("mass_matrix_max_abs_diff", 0.0) < 1e-9
    ok = ok and out.get("bias_max_abs_diff", 0.0) < 1e-9
    out["ok"] = bool(ok)
    return out


def _compare_with_pinocchio(model: mujoco.MjModel) -> dict:
    """M + J_m and h + g at q0 against pinocchio on config/paper_4link.urdf (if present)."""
    urdf = Path(__file__).resolve().parents[1] / "config" / "paper_4link.urdf"
    try:
        import pinocchio as pin
    except ImportError:
        return {"pinocchio_check": "skipped (no pinocchio)"}
    if not urdf.is_file():
        return {"pinocchio_check": f"skipped (no {urdf})"}
    pmodel = pin.buildModelFromUrdf(str(urdf))
    pdata = pmodel.createData()
    q = np.array(Q0)
    m_pin = pin.crba(pmodel, pdata, q)
    m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T + ARMATURE * np.eye(model.nv)
    h_pin = pin.nonLinearEffects(pmodel, pdata, q, np.zeros(model.nv))
    data = mujoco.MjData(model)
    data.qpos[:] = Q0
    mujoco.mj_forward(model, data)
    m_mj = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m_mj)  # mujoco >= 3.5 signature (qM is gone in 4.x)
    return {
        "pinocchio_check": "done",
        "mass_matrix_max_abs_diff": float(np.max(np.abs(m_mj - m_pin))),
        "bias_max_abs_diff": float(np.max(np.abs(data.qfrc_bias - h_pin))),
    }


def _segments(n_steps: int) -> list[int]:
    full, rest = divmod(n_steps, SEGMENT_STEPS)
    return [SEGMENT_STEPS] * full + ([rest] if rest else [])


def mujoco_steps_per_s(n_steps: int = 10000, repeats: int = 5) -> dict:
    """Median (and samples) of mj_step calls/s in a Python loop, one qfrc_applied write per step.

    Each repeat restarts from q0 at rest with the elbow on the floor, and again every
    SEGMENT_STEPS steps (untimed) so the contact stays active. Also reports, for
    reference, the same number of steps done inside MuJoCo (``mj_step(..., nstep=n)``),
    i.e. without the Python loop.
    """
    model, data = build()
    tau = constant_input(model, data)
    qfrc = data.qfrc_applied
    step = mujoco.mj_step

    # warm-up (caches, lazy allocations)
    reset(model, data)
    for _ in range(min(500, n_steps)):
        qfrc[:] = tau
        step(model, data)

    samples: list[float] = []
    contacts_ok = True
    for _ in range(repeats):
        elapsed = 0.0
        for seg in _segments(n_steps):
            reset(model, data)
            t0 = time.perf_counter()
            for _ in range(seg):
                qfrc[:] = tau
                step(model, data)
            elapsed += time.perf_counter() - t0
            contacts_ok = contacts_ok and data.ncon >= 1
        samples.append(n_steps / elapsed)

    native: list[float] = []
    for _ in range(repeats):
        elapsed = 0.0
        for seg in _segments(n_steps):
            reset(model, data)
            qfrc[:] = tau
            t0 = time.perf_counter()
            step(model, data, seg)
            elapsed += time.perf_counter() - t0
            contacts_ok = contacts_ok and data.ncon >= 1
        native.append(n_steps / elapsed)

    return {
        "steps_per_s": statistics.median(samples),
        "samples": samples,
        "native_nstep_steps_per_s": statistics.median(native),
        "native_samples": native,
        "n_steps": n_steps,
        "repeats": repeats,
        "contact_active_at_end": bool(contacts_ok),
        "integrator": "RK4",
        "timestep": DT,
        "mujoco_version": mujoco.__version__,
    }


if __name__ == "__main__":
    import json

    print(json.dumps({"sanity": sanity_check(), "timing": mujoco_steps_per_s()}, indent=2))
