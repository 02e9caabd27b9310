"""An animation of a recorded run: the arm in its plane of motion, as GIF (and MP4 with ffmpeg).

Each frame shows the links (pinocchio kinematics of the bag's ``robot_description`` at the
recorded joint positions), the contact surfaces, the contact points with their force
arrows (``contact_wrench``, ``ARROW_M_PER_N`` metres per newton), the hand's target path
and the hand's trail so far, with the time and the normal forces written on it.

Frames are taken every ``interval`` seconds of sim time (frame k shows the recorded state
nearest to t = k * interval) and play in real time. The drawing plane is the pair of world
axes along which the links move most (y-z for the paper's arm).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from bracing_bringup.scene import LinkPoses
from bracing_bringup.summary import BagSeries

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]

DEFAULT_INTERVAL_S = 0.1
"""Sim time between frames [s]: 101 frames for the paper's 10 s, drawn in a few seconds."""

FRAME_SIZE_IN = (6.4, 4.8)
FRAME_DPI = 100
"""640 x 480 pixels: both even, as the MP4 encoder (yuv420p) needs."""

ARROW_M_PER_N = 0.02
"""Force arrows: metres of arrow per newton (f_nd = 10 N -> 0.2 m)."""

LINK_COLOR = "#1f4e9c"
SURFACE_COLOR = "#9a9a9a"
FORCE_COLOR = "#ff8c00"
TARGET_COLOR = "#d62728"
TRAIL_COLOR = "#2ca02c"
AXIS_NAMES = ("x", "y", "z")


class AnimationError(ValueError):
    """The bag cannot be animated (no joint states, or no robot description)."""


def frame_times(end_s: float, interval_s: float) -> FloatArray:
    """0, interval, 2 interval, ... up to ``end_s`` (inclusive, within a nanosecond)."""
    if interval_s <= 0:
        msg = f"frame interval must be > 0, got {interval_s}"
        raise AnimationError(msg)
    count = int(np.floor(end_s / interval_s + 1e-9)) + 1
    return np.arange(count, dtype=np.float64) * interval_s


def nearest(stamps: FloatArray, times: FloatArray) -> NDArray[np.intp]:
    """Index of the stamp nearest to each time (stamps sorted, not empty)."""
    right = np.clip(np.searchsorted(stamps, times), 1, max(stamps.size - 1, 1))
    left = right - 1
    if stamps.size == 1:
        return np.zeros(times.size, dtype=np.intp)
    take_left = np.abs(times - stamps[left]) <= np.abs(stamps[right] - times)
    return np.where(take_left, left, right).astype(np.intp)


def plane_axes(points: FloatArray) -> tuple[int, int]:
    """The two world axes along which ``points`` (..., 3) spread most, in x, y, z order."""
    spread = np.ptp(points.reshape(-1, 3), axis=0)
    first, second = sorted(np.argsort(spread)[-2:].tolist())
    return int(first), int(second)


@dataclass
class ContactFrames:
    """One contact at the frame times (NaN where nothing was recorded)."""

    name: str
    position: FloatArray  # (frames, 3) [m]
    normal: FloatArray  # (frames, 3)
    force: FloatArray  # (frames, 3) [N]
    normal_force: FloatArray  # (frames,) [N]


class ArmAnimation:
    """The frames of one run, drawn with matplotlib (imported only here, when drawing)."""

    def __init__(self, series: BagSeries, interval_s: float = DEFAULT_INTERVAL_S, urdf: str | None = None) -> None:
        description = urdf if urdf is not None else series.robot_description
        if description is None:
            msg = "the bag has no robot_description (recorded by an older version); pass the URDF to animate it"
            raise AnimationError(msg)
        if series.joint_t.size == 0:
            msg = "the bag has no joint_states"
            raise AnimationError(msg)
        self.series = series
        self.interval = interval_s
        self.poses = LinkPoses(description)
        self.times = frame_times(float(series.joint_t[-1]), interval_s)
        states = nearest(series.joint_t, self.times)
        names = series.joint_names
        self.links = np.array(
            [self.poses.positions(self.poses.configuration(names, series.joint_position[k])) for k in states]
        )  # (frames, bodies, 3)
        self.segments = self.poses.segments()
        self.contacts = [self._contact_frames(cs) for cs in series.contacts.values() if cs.t.size]
        self.axes = plane_axes(self.links)
        self._fig: Figure | None = None
        self._artists: dict[str, Any] = {}

    def _contact_frames(self, cs: Any) -> ContactFrames:
        idx = nearest(cs.t, self.times)
        force = np.full((self.times.size, 3), np.nan)
        if cs.t_force.size:
            force = cs.force[nearest(cs.t_force, self.times)]
        return ContactFrames(cs.name, cs.position[idx], cs.normal[idx], force, cs.normal_force[idx])

    # -- geometry in the drawing plane ---------------------------------------------------
    def _2d(self, points: FloatArray) -> FloatArray:
        a, b = self.axes
        return np.asarray(points)[..., [a, b]]

    def _limits(self) -> tuple[tuple[float, float], tuple[float, float]]:
        pts = [self._2d(self.links).reshape(-1, 2)]
        if self.series.hand_desired.size:
            pts.append(self._2d(self.series.hand_desired))
        for c in self.contacts:
            pts.append(self._2d(c.position[np.isfinite(c.position).all(axis=1)]))
        allpts = np.concatenate(pts)
        allpts = allpts[np.isfinite(allpts).all(axis=1)]
        lo, hi = allpts.min(axis=0) - 0.2, allpts.max(axis=0) + 0.2
        return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))

    # -- drawing -------------------------------------------------------------------------
    def figure(self) -> Figure:
        """The figure, with every artist created (frame 0 not drawn yet)."""
        if self._fig is not None:
            return self._fig
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import FancyArrowPatch, Polygon

        fig = Figure(figsize=FRAME_SIZE_IN, dpi=FRAME_DPI)
        FigureCanvasAgg(fig)  # frames are read from the Agg buffer
        # Fixed margins (no layout engine): the same data maps to the same pixel in every frame.
        ax = fig.add_axes((0.1, 0.1, 0.85, 0.8))
        (x0, x1), (y0, y1) = self._limits()
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal", adjustable="box")
        a, b = self.axes
        ax.set_xlabel(f"{AXIS_NAMES[a]} [m]")
        ax.set_ylabel(f"{AXIS_NAMES[b]} [m]")
        ax.grid(True, alpha=0.3)
        art: dict[str, Any] = {}
        for c in self.contacts:
            ok = np.isfinite(c.normal).all(axis=1)
            if not ok.any():
                continue
            n3 = c.normal[ok][0]
            p3 = c.position[ok][0]
            n2 = self._2d(n3)
            if np.linalg.norm(n2) < 1e-9:
                continue  # the surface is parallel to the drawing plane
            n2 = n2 / np.linalg.norm(n2)
            along = np.array([-n2[1], n2[0]])
            centre = self._2d(p3)
            span = 10.0 * max(x1 - x0, y1 - y0)
            depth = 0.04 * max(x1 - x0, y1 - y0)
            corners = [
                centre - span * along,
                centre + span * along,
                centre + span * along - depth * n2,
                centre - span * along - depth * n2,
            ]
            ax.add_patch(Polygon(np.array(corners), closed=True, color=SURFACE_COLOR, alpha=0.5, lw=0))
            ax.axline(tuple(centre), tuple(centre + along), color=SURFACE_COLOR, lw=2)
        if self.series.hand_desired.size:
            path = self._2d(self.series.hand_desired)
            ax.plot(path[:, 0], path[:, 1], "--", color=TARGET_COLOR, lw=1.2, label="hand target path")
        # What changes per frame is "animated": left out of the full draw, drawn over a saved background.
        moving: list[Any] = []
        (trail,) = ax.plot([], [], color=TRAIL_COLOR, lw=1.5, label="hand trail", animated=True)
        (target,) = ax.plot([], [], "x", color=TARGET_COLOR, ms=8, mew=2, animated=True)
        (links,) = ax.plot([], [], "-", color=LINK_COLOR, lw=4, solid_capstyle="round", label="links", animated=True)
        (joints,) = ax.plot([], [], "o", color="white", mec=LINK_COLOR, ms=5, mew=1.5, animated=True)
        moving += [trail, target, links, joints]
        art.update(trail=trail, target=target, links=links, joints=joints, points=[], arrows=[])
        for _ in self.contacts:
            (point,) = ax.plot([], [], "o", color="#c0392b", ms=7, animated=True)
            arrow = FancyArrowPatch((0, 0), (0, 0), arrowstyle="-|>", mutation_scale=14, color=FORCE_COLOR, lw=2.5)
            arrow.set_animated(True)
            ax.add_patch(arrow)
            art["points"].append(point)
            art["arrows"].append(arrow)
            moving += [point, arrow]
        if self.contacts:
            ax.plot([], [], "-", color=FORCE_COLOR, lw=2.5, label=f"contact force ({ARROW_M_PER_N * 100:g} cm/N)")
        art["text"] = ax.text(
            0.02, 0.97, "", transform=ax.transAxes, va="top", ha="left", family="monospace", animated=True
        )
        moving.append(art["text"])
        ax.legend(loc="lower right", fontsize=7, framealpha=0.8)
        fig.canvas.draw()
        self._background = fig.canvas.copy_from_bbox(fig.bbox)  # type: ignore[attr-defined]
        self._fig, self._artists, self._ax, self._moving = fig, art, ax, moving
        return fig

    def pixel(self, point: Sequence[float] | FloatArray) -> tuple[int, int]:
        """(column, row) of a world point's projection in a frame image (row 0 at the top)."""
        fig = self.figure()
        x, y = self._ax.transData.transform(self._2d(np.asarray(point, dtype=float)))
        height = round(float(fig.get_figheight() * fig.dpi))
        return round(float(x)), round(height - float(y))

    def draw(self, k: int) -> NDArray[np.uint8]:
        """Frame ``k`` as an RGB image (rows, columns, 3)."""
        fig = self.figure()
        art = self._artists
        t = float(self.times[k])
        pts = self._2d(self.links[k])
        segs = []
        for parent, child in self.segments:
            segs += [pts[parent], pts[child], [np.nan, np.nan]]
        seg = np.array(segs) if segs else np.zeros((0, 2))
        art["links"].set_data(seg[:, 0], seg[:, 1])
        art["joints"].set_data(pts[:, 0], pts[:, 1])
        s = self.series
        if s.t.size:
            upto = s.t <= t + 1e-9
            trail = self._2d(s.hand_actual[upto])
            art["trail"].set_data(trail[:, 0], trail[:, 1])
            if upto.any():
                now = self._2d(s.hand_desired[upto][-1])
                art["target"].set_data([now[0]], [now[1]])
        lines = [f"t = {t:6.2f} s"]
        for c, point, arrow in zip(self.contacts, art["points"], art["arrows"], strict=True):
            p = self._2d(c.position[k])
            point.set_data([p[0]], [p[1]])
            f = c.force[k]
            tip = p + ARROW_M_PER_N * self._2d(f) if np.isfinite(f).all() else p
            arrow.set_positions(tuple(p), tuple(tip))
            lines.append(f"f_n {c.name} = {c.normal_force[k]:7.2f} N")
        art["text"].set_text("\n".join(lines))
        canvas: Any = fig.canvas
        canvas.restore_region(self._background)
        for artist in self._moving:
            self._ax.draw_artist(artist)
        rgba = np.asarray(canvas.buffer_rgba())
        return np.ascontiguousarray(rgba[:, :, :3])

    # -- files ---------------------------------------------------------------------------
    def save(self, gif: Path | None, mp4: Path | None = None) -> list[Path]:
        """Draw every frame once and write it to the GIF (Pillow) and MP4 (ffmpeg, if available)."""
        from PIL import Image

        mp4_writer = _mp4_writer(mp4, self.interval) if mp4 is not None else None
        images = []
        try:
            for k in range(self.times.size):
                frame = self.draw(k)
                if gif is not None:
                    # 64 colours by octree: 4x quicker than Pillow's default and enough for line art.
                    images.append(Image.fromarray(frame).quantize(colors=64, method=Image.Quantize.FASTOCTREE))
                if mp4_writer is not None:
                    mp4_writer.send(frame)
        finally:
            if mp4_writer is not None:
                mp4_writer.close()
        written = []
        if gif is not None:
            duration_ms = max(round(self.interval * 1000), 20)  # GIF viewers play 20 ms frames at best
            images[0].save(gif, save_all=True, append_images=images[1:], duration=duration_ms, loop=0)
            written.append(gif)
        if mp4_writer is not None and mp4 is not None:
            written.append(mp4)
        return written


def _mp4_writer(path: Path, interval_s: float) -> Any:
    """imageio-ffmpeg's frame writer (its bundled ffmpeg), primed; None without imageio-ffmpeg."""
    try:
        import imageio_ffmpeg
    except ImportError:
        return None
    writer = imageio_ffmpeg.write_frames(
        str(path),
        (int(FRAME_SIZE_IN[0] * FRAME_DPI), int(FRAME_SIZE_IN[1] * FRAME_DPI)),
        fps=1.0 / interval_s,
        codec="libx264",
        pix_fmt_out="yuv420p",
        macro_block_size=1,
        quality=7,
        ffmpeg_log_level="error",
    )
    writer.send(None)  # start the generator
    return writer


def write_animation(
    series: BagSeries,
    output_dir: str | Path,
    interval_s: float = DEFAULT_INTERVAL_S,
    urdf: str | None = None,
    mp4: bool = True,
) -> list[Path]:
    """``animation.gif`` (and ``animation.mp4``) of the run in ``output_dir``; the files written."""
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    animation = ArmAnimation(series, interval_s, urdf)
    return animation.save(out / "animation.gif", out / "animation.mp4" if mp4 else None)
