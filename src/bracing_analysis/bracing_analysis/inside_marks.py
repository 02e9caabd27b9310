"""Where the animation marks a link inside a surface (``link_penetration``, robot.collision_geometry; no
rclpy, no matplotlib).

The simulator publishes, per surface and state, the link deepest in it or nearest to it: its deepest
point, the signed distance (negative inside) and whether it is deeper than robot.penetration_tolerance
(``active``). At each frame time the animation takes each surface's nearest recorded sample and marks
the point of a link that is inside, with the link's name and depth written beside the forces.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from bracing_analysis.series import BagSeries, FloatArray


@dataclass
class InsideFrames:
    """One surface at the frame times: the deepest point of a link inside it (NaN where none is) and
    what the frame says of it ("" where no link is inside)."""

    surface: str  # the contact whose surface it is
    position: FloatArray  # (frames, 3) [m], world
    label: list[str]

    def inside(self, k: int) -> bool:
        return bool(np.isfinite(self.position[k]).all())


def inside_frames(series: BagSeries, sample_at: Callable[[FloatArray], NDArray[np.intp]]) -> list[InsideFrames]:
    """Every surface of ``series.link_penetration`` that some link went inside; ``sample_at(stamps)`` is the
    index of the stamp nearest to each frame time."""
    out = []
    for surface, recorded in series.link_penetration.items():
        if not recorded.t.size or not np.any(recorded.inside):
            continue
        idx = sample_at(recorded.t)
        inside = recorded.inside[idx]
        position = np.where(inside[:, None], recorded.position[idx], np.nan)
        depth_mm = -1000.0 * recorded.distance[idx]
        label = [
            f"{recorded.link[i]} {d:5.1f} mm inside {surface}" if now else ""
            for i, d, now in zip(idx.tolist(), depth_mm.tolist(), inside.tolist(), strict=True)
        ]
        out.append(InsideFrames(surface, position, label))
    return out
