"""An animation of a recorded run: the arm in its plane of motion, as GIF (and MP4 with ffmpeg).

Each frame shows the links (pinocchio kinematics of the bag's ``robot_description`` at the
recorded joint positions), the contact surfaces (each once), the contact points with their force
arrows (``contact_wrench``, ``ARROW_M_PER_N`` metres per newton; a kept-out frame or link,
``<frame>@<contact>``, only while it touches), a link inside a surface (``link_penetration``: its
deepest point, its name and depth; ``inside_marks``), the hand's target path
and the hand's trail so far, with the time and the normal forces written on it. A plane is drawn
as its line in the drawing plane, the solid side shaded; a sphere or a cylinder whose geometry the
bag holds (``surfaces``) as its outline seen along the third axis: a sphere a disc, a cylinder a
band (or a disc, its axis along the view); one that the frame stays inside, as its outline only.

A link whose URDF visual is a mesh the machine has (``bracing_core.meshes``: the file:// paths the
simulator publishes, package:// through the ament index and ROS_PACKAGE_PATH) is also drawn as the
mesh's outline in the plane (``MeshOutline``), shaded under its line; a mesh not found leaves the line.

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

from bracing_analysis.frame_files import (
    FORCE_COLOR,
    FRAME_DPI,
    FRAME_SIZE_IN,
    LINK_COLOR,
    POINT_COLOR,
    SURFACE_COLOR,
    TARGET_COLOR,
    TRAIL_COLOR,
    GifWriter,
    GlyphText,
    Palette,
    start_mp4,
)
from bracing_analysis.inside_marks import inside_frames
from bracing_analysis.series import BagSeries
from bracing_analysis.surfaces import Shape, shape_of
from bracing_core.contact_roles import KEPT_OUT, role, surface_owner
from bracing_core.kinematics import LinkPoses
from bracing_core.meshes import read_mesh, resolve, visual_meshes

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]

ANIMATION_FILES = ("animation.gif", "animation.mp4")
"""What ``write_animation`` writes (the MP4 where ffmpeg is available)."""

DEFAULT_INTERVAL_S = 0.1
"""Sim time between frames [s]: 101 frames for the paper's 10 s, drawn and written in about 0.6 s."""

ARROW_M_PER_N = 0.02
"""Force arrows: metres of arrow per newton (f_nd = 10 N -> 0.2 m)."""

TRAIL_STEP_S = 0.005
"""The hand trail goes through the hand's samples this far apart (and its latest): 5 mm at 1 m/s,
about a pixel; all 10 000 samples of a 10 s run took a third of a frame's drawing."""

AXIS_NAMES = ("x", "y", "z")
MESH_ALPHA = 0.3
"""A mesh's outline: the link's colour, this opaque."""
SUPPORT_DIRECTIONS = 256
"""A mesh is kept as its extreme points along this many directions (``MeshOutline``)."""
OUTLINE_DIRECTIONS = 64
"""A mesh's outline in the drawing plane: its extreme points along this many directions of the plane."""


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


def _sphere_directions(count: int) -> FloatArray:
    """``count`` unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(count) + 0.5
    z = 1.0 - 2.0 * k / count
    azimuth = np.pi * (1.0 + 5.0**0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(azimuth), r * np.sin(azimuth), z], axis=1)


@dataclass
class MeshOutline:
    """A link's mesh visual, for its outline: its extreme points along ``SUPPORT_DIRECTIONS`` directions
    (at most that many of its vertices), in the link's frame (the visual's origin and scale applied).
    Seen in any plane, the outline of these points is the mesh's to a pixel or two at the animation's
    size (an inner polygon of its convex outline)."""

    row: int  # the link's row of LinkPoses.body_names
    points: FloatArray  # (n, 3) [m]


def mesh_outlines(description: str, poses: LinkPoses) -> list[MeshOutline]:
    """The mesh visuals of ``description`` that this machine has and reads (``bracing_core.meshes``)."""
    import pinocchio as pin  # imported where used: only for a URDF with meshes

    rows = {name: row for row, name in enumerate(poses.body_names)}
    directions = _sphere_directions(SUPPORT_DIRECTIONS).T
    out = []
    for visual in visual_meshes(description):
        path = resolve(visual.uri)
        read = read_mesh(path) if path is not None and visual.link in rows else None
        if read is None:
            continue
        rotation = pin.rpy.rpyToMatrix(*visual.rpy)
        vertices = (read[0] * np.asarray(visual.scale, dtype=float)) @ rotation.T + np.asarray(visual.xyz, dtype=float)
        best = np.full(directions.shape[1], -np.inf)
        chosen = np.zeros(directions.shape[1], dtype=np.intp)
        for start in range(0, len(vertices), 8192):  # a big mesh's products a block at a time
            along = vertices[start : start + 8192] @ directions
            top = np.argmax(along, axis=0)
            value = along[top, np.arange(along.shape[1])]
            better = value > best
            best[better], chosen[better] = value[better], top[better] + start
        out.append(MeshOutline(rows[visual.link], vertices[np.unique(chosen)]))
    return out


@dataclass
class ContactFrames:
    """One contact at the frame times (NaN where nothing was recorded)."""

    name: str
    position: FloatArray  # (frames, 3) [m]
    normal: FloatArray  # (frames, 3)
    force: FloatArray  # (frames, 3) [N]
    normal_force: FloatArray  # (frames,) [N]
    residual: FloatArray  # (frames,) [m] off the surface along the normal
    kept_out: bool = False  # a frame or link kept out of a surface: drawn only while it touches


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
        self.outlines = mesh_outlines(description, self.poses) if "<mesh" in description else []
        links, meshes = [], []
        for k in states:
            links.append(self.poses.positions(self.poses.configuration(names, series.joint_position[k])))
            placed = [self.poses.data.oMf[self.poses.body_ids[m.row]] for m in self.outlines]
            meshes.append([m.points @ o.rotation.T + o.translation for m, o in zip(self.outlines, placed, strict=True)])
        self.links = np.array(links)  # (frames, bodies, 3)
        self.meshes = meshes  # per frame, per outline: its points in the world [m]
        self.segments = self.poses.segments()
        recorded = [cs for cs in series.contacts.values() if cs.t.size]
        # The scenario's contacts first: each surface is drawn from its owner's samples (_draw_surfaces).
        self.contacts = [self._contact_frames(cs) for cs in sorted(recorded, key=lambda cs: role(cs.name) == KEPT_OUT)]
        self.inside = inside_frames(series, lambda stamps: nearest(stamps, self.times))
        self.axes = plane_axes(self.links)
        # Per frame: the number of hand samples up to its time (the trail so far, the target now).
        self.hand_count = np.searchsorted(series.t, self.times + 1e-9, side="right")
        sample_s = float(np.median(np.diff(series.t))) if series.t.size > 1 else 0.0
        self._trail_step = max(1, round(TRAIL_STEP_S / sample_s)) if sample_s > 0 else 1
        self._fig: Figure | None = None
        self._artists: dict[str, Any] = {}

    def _contact_frames(self, cs: Any) -> ContactFrames:
        idx = nearest(cs.t, self.times)
        force = np.full((self.times.size, 3), np.nan)
        if cs.t_force.size:
            force = cs.force[nearest(cs.t_force, self.times)]
        position, kept_out = cs.position[idx], role(cs.name) == KEPT_OUT
        if kept_out and cs.active.shape == cs.t.shape:  # a kept-out frame or link: only where it touches
            position = np.where(cs.active[idx, None], position, np.nan)
        residual = cs.residual[idx] if cs.residual.shape == cs.t.shape else np.zeros(idx.size)
        return ContactFrames(cs.name, position, cs.normal[idx], force, cs.normal_force[idx], residual, kept_out)

    # -- geometry in the drawing plane ---------------------------------------------------
    def _2d(self, points: FloatArray) -> FloatArray:
        a, b = self.axes
        return np.asarray(points)[..., [a, b]]

    def _limits(self) -> tuple[tuple[float, float], tuple[float, float]]:
        pts = [self._2d(self.links).reshape(-1, 2)]
        pts += [self._2d(points) for frame in self.meshes for points in frame]
        if self.series.hand_desired.size:
            pts.append(self._2d(self.series.hand_desired))
        for c in self.contacts:
            pts.append(self._2d(c.position[np.isfinite(c.position).all(axis=1)]))
        allpts = np.concatenate(pts)
        allpts = allpts[np.isfinite(allpts).all(axis=1)]
        lo, hi = allpts.min(axis=0) - 0.2, allpts.max(axis=0) + 0.2
        return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))

    def _link_lines(self) -> FloatArray:
        """(frames, 3 * segments, 2): parent, child, NaN (a break) for every segment, in the plane."""
        pts = self._2d(self.links)
        lines = np.full((pts.shape[0], 3 * len(self.segments), 2), np.nan)
        for i, (parent, child) in enumerate(self.segments):
            lines[:, 3 * i] = pts[:, parent]
            lines[:, 3 * i + 1] = pts[:, child]
        return lines

    def _mesh_lines(self) -> list[list[FloatArray]]:
        """Per frame, each mesh's outline in the plane: its extreme points along ``OUTLINE_DIRECTIONS``
        directions of the plane, in their order around it (a convex polygon)."""
        angles = np.linspace(0.0, 2.0 * np.pi, OUTLINE_DIRECTIONS, endpoint=False)
        around = np.stack([np.cos(angles), np.sin(angles)])
        out = []
        for frame in self.meshes:
            flat = [self._2d(points) for points in frame]
            out.append([xy[np.argmax(xy @ around, axis=0)] for xy in flat])
        return out

    # -- drawing -------------------------------------------------------------------------
    def figure(self) -> Figure:
        """The figure, with every artist created (frame 0 not drawn yet)."""
        if self._fig is not None:
            return self._fig
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # matplotlib ~460 ms, where used
        from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

        fig = Figure(figsize=FRAME_SIZE_IN, dpi=FRAME_DPI)
        FigureCanvasAgg(fig)  # frames are read from the Agg buffer
        ax, size = self._axes(fig)
        self._draw_surfaces(ax, size)
        if self.series.hand_desired.size:
            path = self._2d(self.series.hand_desired)
            ax.plot(path[:, 0], path[:, 1], "--", color=TARGET_COLOR, lw=1.2, label="hand target path")
        art, moving = self._moving_artists(ax)
        ax.legend(loc="lower right", fontsize=7, framealpha=0.8)
        fig.canvas.draw()
        self._background = fig.canvas.copy_from_bbox(fig.bbox)  # type: ignore[attr-defined]
        self._fig, self._artists, self._ax, self._moving = fig, art, ax, moving
        self._link_xy = self._link_lines()
        self._mesh_xy = self._mesh_lines()
        self._hand_xy = self._2d(self.series.hand_actual)
        self._target_xy = self._2d(self.series.hand_desired)
        return fig

    def _axes(self, fig: Figure) -> tuple[Axes, float]:
        """The plane's axes with fixed margins (no layout engine: the same data maps to the same pixel
        in every frame), and the drawing's size [m]."""
        ax = fig.add_axes((0.1, 0.1, 0.85, 0.8))
        (x0, x1), (y0, y1) = self._limits()
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal", adjustable="box")
        a, b = self.axes
        ax.set_xlabel(f"{AXIS_NAMES[a]} [m]")
        ax.set_ylabel(f"{AXIS_NAMES[b]} [m]")
        ax.grid(True, alpha=0.3)
        return ax, max(x1 - x0, y1 - y0)

    def _draw_surfaces(self, ax: Axes, size: float) -> None:
        """Each surface once (a kept-out contact is on its owner's, two contacts may share one): a curved
        solid's outline, or a plane as a band under its line."""
        from matplotlib.patches import Polygon  # imported where used: matplotlib ~460 ms (python -X importtime)

        owners: set[str] = set()
        shapes: set[Shape] = set()
        for c in self.contacts:
            shape, owner = shape_of(self.series.surfaces, c.name), surface_owner(c.name)
            curved = shape is not None and shape.curved and shape.radius > 0.0
            ok = np.isfinite(c.normal).all(axis=1) & np.isfinite(c.position).all(axis=1)
            if owner in owners or (shape is not None and shape in shapes) or not (curved or ok.any()):
                continue
            owners.add(owner)
            if shape is not None:
                shapes.add(shape)
            if shape is not None and curved:
                self._draw_solid(ax, shape, 10.0 * size)
                continue
            n2 = self._2d(c.normal[ok][0])
            if np.linalg.norm(n2) < 1e-9:
                continue  # the surface is parallel to the drawing plane
            n2 = n2 / np.linalg.norm(n2)
            along = np.array([-n2[1], n2[0]])
            first = int(np.flatnonzero(ok)[0])
            centre = self._2d(c.position[first] - c.residual[first] * c.normal[first])  # on the surface
            span = 10.0 * size
            depth = 0.04 * size
            corners = [
                centre - span * along,
                centre + span * along,
                centre + span * along - depth * n2,
                centre - span * along - depth * n2,
            ]
            ax.add_patch(Polygon(np.array(corners), closed=True, color=SURFACE_COLOR, alpha=0.5, lw=0))
            ax.axline(tuple(centre), tuple(centre + along), color=SURFACE_COLOR, lw=2)

    def _moving_artists(self, ax: Axes) -> tuple[dict[str, Any], list[Any]]:
        """What changes per frame is "animated": left out of the full draw, drawn over a saved background."""
        from matplotlib.patches import FancyArrowPatch, Polygon  # matplotlib ~460 ms, where used

        art: dict[str, Any] = {}
        moving: list[Any] = []
        for _ in self.outlines:  # under the links' lines
            outline = Polygon(np.zeros((3, 2)), closed=True, color=LINK_COLOR, alpha=MESH_ALPHA, lw=0, animated=True)
            ax.add_patch(outline)
            moving.append(outline)
        art["meshes"] = list(moving)
        (trail,) = ax.plot([], [], color=TRAIL_COLOR, lw=1.5, label="hand trail", animated=True)
        (target,) = ax.plot([], [], "x", color=TARGET_COLOR, ms=8, mew=2, animated=True)
        (links,) = ax.plot([], [], "-", color=LINK_COLOR, lw=4, solid_capstyle="round", label="links", animated=True)
        (joints,) = ax.plot([], [], "o", color="white", mec=LINK_COLOR, ms=5, mew=1.5, animated=True)
        moving += [trail, target, links, joints]
        art.update(trail=trail, target=target, links=links, joints=joints, points=[], arrows=[])
        for _ in self.contacts:
            (point,) = ax.plot([], [], "o", color=POINT_COLOR, ms=7, animated=True)
            # No shrinking of the ends (matplotlib's default 2 points costs 0.7 ms a frame in its
            # bisection): the arrow runs from the contact point to exactly ARROW_M_PER_N * force.
            arrow = FancyArrowPatch(
                (0, 0), (0, 0), arrowstyle="-|>", mutation_scale=14, color=FORCE_COLOR, lw=2.5, shrinkA=0, shrinkB=0
            )
            arrow.set_animated(True)
            ax.add_patch(arrow)
            art["points"].append(point)
            art["arrows"].append(arrow)
            moving += [point, arrow]
        if self.contacts:
            ax.plot([], [], "-", color=FORCE_COLOR, lw=2.5, label=f"contact force ({ARROW_M_PER_N * 100:g} cm/N)")
        art["inside"] = []
        for k, _ in enumerate(self.inside):  # a link inside a surface: its deepest point
            label = "link inside a surface" if k == 0 else None
            (mark,) = ax.plot([], [], "X", color=POINT_COLOR, mec="black", ms=11, label=label, animated=True)
            art["inside"].append(mark)
            moving.append(mark)
        art["text"] = GlyphText(ax, 0.02, 0.97)
        moving.append(art["text"].patch)
        return art, moving

    def _draw_solid(self, ax: Axes, shape: Shape, span: float) -> None:
        """A sphere or a cylinder as seen along the axis normal to the drawing plane (its outline):
        filled, unless the frame stays inside it (then the solid is all around: its outline only)."""
        from matplotlib.patches import Circle, Polygon  # imported where used: matplotlib ~460 ms (python -X importtime)

        fill = dict(color=SURFACE_COLOR, alpha=0.5, lw=0)
        edge = dict(color=SURFACE_COLOR, lw=2)
        axis = self._2d(np.array(shape.axis))
        if shape.kind == "sphere" or float(np.linalg.norm(axis)) < 1e-9:  # a disc (a cylinder seen end on)
            centre = self._2d(np.array(shape.center if shape.kind == "sphere" else shape.point))
            if not shape.inside:
                ax.add_patch(Circle(tuple(centre), shape.radius, **fill))  # type: ignore[arg-type]
            ax.add_patch(Circle(tuple(centre), shape.radius, fill=False, **edge))  # type: ignore[arg-type]
            return
        # A cylinder whose axis shows in the plane: a band of half-width r about the axis's projection
        # (the orthographic outline of a cylinder, whatever the axis's tilt out of the plane).
        along = axis / np.linalg.norm(axis)
        across = np.array([-along[1], along[0]]) * shape.radius
        centre = self._2d(np.array(shape.point))
        if not shape.inside:
            corners = [centre - span * along + across, centre + span * along + across]
            corners += [centre + span * along - across, centre - span * along - across]
            ax.add_patch(Polygon(np.array(corners), closed=True, **fill))  # type: ignore[arg-type]
        for side in (across, -across):
            ax.axline(tuple(centre + side), tuple(centre + side + along), **edge)  # type: ignore[arg-type]

    def pixel(self, point: Sequence[float] | FloatArray) -> tuple[int, int]:
        """(column, row) of a world point's projection in a frame image (row 0 at the top)."""
        fig = self.figure()
        x, y = self._ax.transData.transform(self._2d(np.asarray(point, dtype=float)))
        height = round(float(fig.get_figheight() * fig.dpi))
        return round(float(x)), round(height - float(y))

    def draw(self, k: int) -> NDArray[np.uint8]:
        """Frame ``k`` as an RGBA image (rows, columns, 4): a view of the canvas, which the next draw
        overwrites.

        Blitted: the static parts (axes, grid, surfaces, target path, legend) are drawn once by
        ``figure`` and restored here, and only the moving artists are drawn over them."""
        fig = self.figure()
        art = self._artists
        t = float(self.times[k])
        links = self._link_xy[k]
        art["links"].set_data(links[:, 0], links[:, 1])
        for outline, xy in zip(art["meshes"], self._mesh_xy[k], strict=True):
            outline.set_xy(xy)
        joints = self._2d(self.links[k])
        art["joints"].set_data(joints[:, 0], joints[:, 1])
        n = int(self.hand_count[k])
        latest = max(n - 1, 0)
        trail = np.concatenate([self._hand_xy[: latest : self._trail_step], self._hand_xy[latest:n]])
        art["trail"].set_data(trail[:, 0], trail[:, 1])
        if n:
            art["target"].set_data(self._target_xy[n - 1 : n, 0], self._target_xy[n - 1 : n, 1])
        lines = [f"t = {t:6.2f} s"]
        for c, point, arrow in zip(self.contacts, art["points"], art["arrows"], strict=True):
            p = self._2d(c.position[k])
            point.set_data([p[0]], [p[1]])
            f = c.force[k]
            tip = p + ARROW_M_PER_N * self._2d(f) if np.isfinite(f).all() else p
            arrow.set_visible(bool(np.isfinite(p).all()))  # a kept-out frame or link away from its surface: none
            if arrow.get_visible():
                arrow.set_positions(tuple(p), tuple(tip))
            if not c.kept_out or np.isfinite(p).all():
                lines.append(f"f_n {c.name} = {c.normal_force[k]:7.2f} N")
        for mark, surface in zip(art["inside"], self.inside, strict=True):
            p = self._2d(surface.position[k])
            mark.set_data([p[0]], [p[1]])
            if surface.inside(k):
                lines.append(surface.label[k])
        art["text"].set_text("\n".join(lines))
        canvas: Any = fig.canvas
        canvas.restore_region(self._background)
        for artist in self._moving:
            self._ax.draw_artist(artist)
        return np.asarray(canvas.buffer_rgba())

    # -- files ---------------------------------------------------------------------------
    def save(self, gif: Path | None, mp4: Path | None = None) -> list[Path]:
        """Draw every frame once, reduce it to ``Palette``, and write it to the GIF and the MP4
        (ffmpeg, if available) as it is drawn.

        write_animation, 10 s run (101 frames, GIF + MP4): 2.3 s -> 0.55 s (best of 3 on this 2-core
        machine, 0.52-0.61 s between sessions; interleaved with the old code, medians 2.5 -> 0.7 s).
        Per frame, the drawing went from 12 to 2 ms (``GlyphText``, unshrunk arrows, a thinned trail;
        it was blitted already) and the GIF from 6.5 to 1.8 ms (``Palette``, ``GifWriter``); ffmpeg
        (0.85 -> 0.3 s of CPU) reads the palette indices, a quarter of RGBA's bytes, and encodes them
        with one thread and x264's ultrafast preset, beside the drawing. What is left: about 0.1 s of
        figure setup (axis ticks), and ffmpeg slowing the drawing by a third as the two cores share
        their work.
        """
        palette = Palette()
        mp4_writer = start_mp4(mp4, self.interval) if mp4 is not None else None
        # GIF viewers play 20 ms frames at best.
        gif_writer = GifWriter(gif, palette, max(round(self.interval * 1000), 20)) if gif is not None else None
        complete = False
        try:
            for k in range(self.times.size):
                index = palette.index(self.draw(k))
                if mp4_writer is not None:
                    mp4_writer.send(index.tobytes() + palette.ffmpeg)
                if gif_writer is not None:
                    gif_writer.add(index)
            complete = True
        finally:
            if mp4_writer is not None:
                mp4_writer.close()
            if gif_writer is not None:
                gif_writer.close(complete)
        written = [gif] if gif is not None else []
        if mp4 is not None and mp4_writer is not None:
            written.append(mp4)
        return written


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
    gif, movie = ANIMATION_FILES
    return animation.save(out / gif, out / movie if mp4 else None)
