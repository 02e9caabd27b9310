"""bracing-view: what it logs to rerun (fast, from a .rrd), and the served page in a real browser."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")

from bracing_analysis.bag import read_series  # noqa: E402
from bracing_view import view  # noqa: E402

REQUIRE_BROWSER = "BRACING_REQUIRE_BROWSER"
INSTALL_HINT = "install Debian's chromium (apt-get install chromium) and the pinned playwright (make setup)"


def test_logged_entities_and_counts(runs: dict[str, Path], tmp_path: Path) -> None:
    bag = runs["braced"] / "bag"
    series = read_series(bag)
    counts = view.write_rrd(bag, tmp_path / "run.rrd", period_s=0.0)  # every state drawn
    assert (tmp_path / "run.rrd").stat().st_size > 0
    states = len(series.joint_t)
    links = read_links(series.robot_description or "")
    for link in links:
        assert counts[f"world/robot/{link}"] == states
    assert counts["world/skeleton"] == states
    contact = next(iter(series.contacts))
    for entity in ("point", "normal_force", "friction_force"):
        assert counts[f"world/contacts/{contact}/{entity}"] == len(series.contacts[contact].t)
    assert counts[f"world/surfaces/{contact}"] == 1
    assert counts[f"plots/normal_force/{contact}/f_nd"] == len(series.t)
    for axis in "xyz":
        assert counts[f"plots/hand_error/{axis}"] == len(series.t)
    assert counts["plots/energy/consumed"] == len(series.motor_t)
    assert sum(1 for key in counts if key.startswith("plots/current/")) == len(series.joint_names)
    assert counts["world/hand/desired_path"] == counts["world/hand/actual_path"] == 1


def _contacts_message(store, contacts):  # type: ignore[no-untyped-def]
    """A Contacts message (the project's typestore) of (name, point on the surface, unit normal)."""
    t = store.types
    header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="world")
    states = [
        t["bracing_msgs/msg/ContactState"](
            name=name,
            frame=name,
            active=True,
            position=t["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
            normal=t["geometry_msgs/msg/Vector3"](x=n[0], y=n[1], z=n[2]),
            normal_force=5.0,
            friction_force=0.0,
            slip_velocity=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            residual=0.0,
        )
        for name, p, n in contacts
    ]
    return t["bracing_msgs/msg/Contacts"](header=header, contacts=states)


def test_surfaces_are_drawn_as_their_scenario_says(tmp_path: Path) -> None:
    """A sphere whole at its centre, a cylinder along its axis nearest the contact, a plane as its
    tangent patch turned onto the normal; a collision frame's contact (frame@owner) on its owner's, drawn
    once under the owner's name."""
    from rerun.chunk import RrdReader

    from bracing_analysis.surfaces import Shape
    from bracing_core.typestore import bracing_typestore

    shapes = {
        "ball": Shape("sphere", center=(0.1, 0.0, 0.5), radius=0.4),
        "post": Shape("cylinder", point=(1.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), radius=0.2),
        "wall": Shape("plane", normal=(0.0, 1.0, 0.0), offset=0.3),
    }
    s = 1 / np.sqrt(2)
    contacts = [
        ("ball", (0.1, 0.0, 0.9), (0.0, 0.0, 1.0)),
        ("post", (1.2, 0.0, 0.7), (1.0, 0.0, 0.0)),
        ("tip@wall", (0.5, 0.3, 0.2), (0.0, 1.0, 0.0)),
        ("unknown", (0.0, 0.0, 0.0), (s, s, 0.0)),  # no geometry known: its tangent patch
    ]
    rrd = tmp_path / "surfaces.rrd"
    recording = view.new_recording()
    recording.save(str(rrd))
    feed = view.Feed(recording, 0.0, shapes)
    feed.message("contacts", _contacts_message(bracing_typestore(), contacts))
    recording.flush()
    recording.disconnect()
    rows = {
        chunk.entity_path.replace("\\", ""): chunk.to_record_batch().to_pylist()[0]  # rerun escapes "@"
        for chunk in RrdReader(rrd).store().stream()
        if chunk.entity_path.startswith("/world/surfaces/")
    }
    # Each surface once, named by its owner: the collision frame's is the wall's.
    assert set(rows) == {f"/world/surfaces/{name.rsplit('@', 1)[-1]}" for name, _, _ in contacts}
    ball = rows["/world/surfaces/ball"]
    assert ball["Ellipsoids3D:centers"][0] == pytest.approx([0.1, 0.0, 0.5])
    assert ball["Ellipsoids3D:half_sizes"][0] == pytest.approx([0.4] * 3)
    post = rows["/world/surfaces/post"]
    assert post["Cylinders3D:centers"][0] == pytest.approx([1.0, 0.0, 0.7])  # on the axis, level with the contact
    assert post["Cylinders3D:radii"] == pytest.approx([0.2])
    assert _z_axis(post["Cylinders3D:quaternions"][0]) == pytest.approx([0.0, 0.0, 1.0], abs=1e-6)
    for name, point, normal in contacts[2:]:
        patch = rows[f"/world/surfaces/{name.rsplit('@', 1)[-1]}"]
        assert patch["Boxes3D:centers"][0] == pytest.approx(np.subtract(point, 0.001 * np.array(normal)), abs=1e-6)
        assert _z_axis(patch["Boxes3D:quaternions"][0]) == pytest.approx(normal, abs=1e-6)  # thin along the normal
        assert min(patch["Boxes3D:half_sizes"][0]) == pytest.approx(0.001) == patch["Boxes3D:half_sizes"][0][2]


def _z_axis(xyzw: list[float]) -> list[float]:
    """Where a quaternion (x, y, z, w) turns the z axis."""
    x, y, z, w = xyzw
    return [2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)]


def test_recording_reads_back(runs: dict[str, Path], tmp_path: Path) -> None:
    """The .rrd holds the entities on the sim_time timeline (read back through rerun's own reader)."""
    from rerun.chunk import RrdReader

    rrd = tmp_path / "run.rrd"
    counts = view.write_rrd(runs["braced"] / "bag", rrd, period_s=0.05)
    paths = set(RrdReader(rrd).store().schema().entity_paths())
    assert {"/" + key for key in counts} <= paths
    assert {"/world/skeleton", "/plots/hand_error/y", "/plots/energy/consumed"} <= paths


def test_replay_opens_the_bag_once(runs: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The replay reads the bag through bracing_analysis.bag, one open for its series and its messages."""
    from rosbags.highlevel import AnyReader

    opened: list[object] = []
    real_open = AnyReader.open

    def counted_open(reader: AnyReader) -> None:
        opened.append(reader)
        real_open(reader)

    monkeypatch.setattr(AnyReader, "open", counted_open)
    counts = view.write_rrd(runs["braced"] / "bag", tmp_path / "run.rrd", period_s=0.1)
    assert len(opened) == 1 and counts["world/skeleton"] >= 3


def test_period_thins_states(runs: dict[str, Path], tmp_path: Path) -> None:
    bag = runs["braced"] / "bag"
    every = view.write_rrd(bag, tmp_path / "a.rrd", period_s=0.0)
    thinned = view.write_rrd(bag, tmp_path / "b.rrd", period_s=0.1)
    assert thinned["world/skeleton"] < every["world/skeleton"]
    assert 3 <= thinned["world/skeleton"] <= 5  # a 0.3 s run drawn every 0.1 s of sim time


def read_links(urdf: str) -> list[str]:
    from bracing_core.kinematics import LinkPoses

    return LinkPoses(urdf).body_names


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _browser() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def _skip_or_fail(reason: str) -> None:
    if os.environ.get(REQUIRE_BROWSER):
        pytest.fail(f"{reason} ({REQUIRE_BROWSER} is set: CI must run this test)")
    pytest.skip(f"{reason}: {INSTALL_HINT}")


def test_served_page_draws_in_a_real_browser(runs: dict[str, Path], tmp_path: Path) -> None:
    """bracing-view BAG, then headless chromium (SwiftShader WebGL) shows the 3D view and the plots."""
    browser = _browser()
    if browser is None:
        _skip_or_fail("no chromium on this machine")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _skip_or_fail("playwright is not installed")
    web, grpc = _free_port(), _free_port()
    argv = [sys.executable, "-m", "bracing_view.view", str(runs["braced"] / "bag")]
    argv += ["--web-port", str(web), "--grpc-port", str(grpc), "--exit-after", "240"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        url = _served_url(proc)
        shot = tmp_path / "view.png"
        with sync_playwright() as p:
            chromium = p.chromium.launch(
                executable_path=browser,  # Debian's: playwright downloads no browser of its own
                args=[
                    "--no-sandbox",
                    "--use-angle=swiftshader",
                    "--enable-unsafe-swiftshader",
                    "--ignore-gpu-blocklist",
                ],
            )
            page = chromium.new_page(viewport={"width": 1366, "height": 768})
            page.goto(url)
            _wait_until_drawn(page, shot)
            chromium.close()
    finally:
        proc.terminate()
        proc.wait(20)


def _served_url(proc: subprocess.Popen[str]) -> str:
    assert proc.stdout is not None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.startswith("bracing-view: open "):
            url = line.split("open ", 1)[1].strip()
            assert url.startswith("http://127.0.0.1:")
            return url
        if not line and proc.poll() is not None:
            break
    pytest.fail("bracing-view printed no URL")


def _wait_until_drawn(page: object, shot: Path, timeout: float = 150.0) -> None:
    """The WebAssembly viewer draws 10-60 s after the page loads on SwiftShader: screenshots until
    the 3D view (left) and the plots (right) both hold drawn pixels of several colours."""
    from PIL import Image

    deadline = time.monotonic() + timeout
    last = ""
    while time.monotonic() < deadline:
        time.sleep(5)
        page.screenshot(path=str(shot))  # type: ignore[attr-defined]
        image = np.asarray(Image.open(shot).convert("RGB")).astype(int)
        h, w, _ = image.shape
        body = image[int(0.08 * h) : int(0.9 * h)]
        view3d, plots = body[:, : int(0.55 * w)], body[:, int(0.62 * w) :]
        ok3d, okplots = _drawn(view3d), _colored_lines(plots)
        last = f"3D view drawn: {ok3d}, plots drawn: {okplots}"
        if ok3d and okplots:
            return
    pytest.fail(f"the viewer did not draw within {timeout:g} s ({last}; screenshot {shot})")


def _drawn(region: np.ndarray) -> bool:
    """Not blank: many distinct colours and a real spread of brightness (the arm, the floor, the grid)."""
    colours = len(np.unique(region.reshape(-1, 3) // 8, axis=0))
    return colours > 50 and float(region.std()) > 10.0


def _colored_lines(region: np.ndarray) -> bool:
    """Plotted series: saturated (coloured) pixels, which the empty panels' greys and whites lack."""
    saturation = region.max(axis=2) - region.min(axis=2)
    return int((saturation > 60).sum()) > 500


def test_pair_view_watches_the_run_and_loses_nothing(tmp_path: Path) -> None:
    """bracing-pair --view: the viewer serves on 127.0.0.1 and draws the run as it steps (it subscribes
    once the simulator's run_status says so, so the nodes' wait counts only the recorder), and the
    bag still holds every state."""
    from ros_helpers import pair_argv, run

    out = tmp_path / "run"
    done = run(pair_argv(out, "--duration", "1.0", "--view"), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    log = (out / "logs" / "viewer.log").read_text()
    assert "bracing-view: open http://127.0.0.1:" in log, log
    drawn = [line for line in log.splitlines() if "robot states drawn" in line]
    assert drawn, log
    first, last = (float(v) for v in drawn[-1].split("sim time ", 1)[1].removesuffix(" s").split(" to "))
    assert 0.0 <= first <= 0.3 and 0.7 <= last <= 1.0 + 1e-9, drawn  # from its first tenths of a second
    assert len(read_series(out / "bag").joint_t) == 1001  # every state recorded: nothing lost to the viewer
