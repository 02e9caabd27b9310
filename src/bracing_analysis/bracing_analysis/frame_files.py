"""The files of an animation's frames (no ROS; matplotlib, Pillow and imageio-ffmpeg imported where used):
its colours, the text drawn on each frame (``GlyphText``), the fixed palette every frame is reduced to
(``Palette``), the GIF written as the frames come (``GifWriter``) and the MP4 through ffmpeg (``start_mp4``).
``animation`` draws the frames with them.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from PIL import Image

FloatArray = NDArray[np.float64]

FRAME_SIZE_IN = (6.4, 4.8)
FRAME_DPI = 100
"""640 x 480 pixels: both even, as the MP4 encoder (yuv420p) needs."""

LINK_COLOR = "#1f4e9c"
SURFACE_COLOR = "#9a9a9a"
FORCE_COLOR = "#ff8c00"
TARGET_COLOR = "#d62728"
TRAIL_COLOR = "#2ca02c"
POINT_COLOR = "#c0392b"


class GlyphText:
    """Monospaced lines of text, drawn as one path of glyph outlines that are each made once.

    matplotlib's ``Text`` lays out and rasterises every glyph anew at each draw (4 ms for a frame's
    two lines with matplotlib 3.11, more than the rest of the frame). Here each character's outline
    is made once (``TextPath``), and a frame's text is those outlines moved to their cells and
    filled as one ``PathPatch`` (0.2 ms). Placed where ``ax.text(x, y, text, va="top", ha="left",
    family="monospace")`` puts it: top left at (x, y) in axes fraction, characters the renderer's
    (whole pixel) advance apart, lines the font's line height (its OS/2 metrics) apart.
    """

    def __init__(self, ax: Axes, x: float, y: float) -> None:
        import matplotlib as mpl  # imported where used: matplotlib ~460 ms (python -X importtime)
        from matplotlib.font_manager import FontProperties, findfont, get_font  # matplotlib ~460 ms, where used
        from matplotlib.patches import PathPatch  # imported where used: matplotlib ~460 ms (python -X importtime)
        from matplotlib.path import Path as MplPath  # imported where used: matplotlib ~460 ms (python -X importtime)
        from matplotlib.transforms import ScaledTranslation  # matplotlib ~460 ms, where used

        fig = ax.get_figure(root=True)
        assert fig is not None
        self._prop = FontProperties(family="monospace")
        self._px_per_pt = fig.dpi / 72
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        width, _, _ = renderer.get_text_width_height_descent("0" * 10, self._prop, ismath=False)
        self._advance = width / 10  # [px], every character's
        font = get_font(findfont(self._prop))
        metrics = font.get_sfnt_table("OS/2")
        assert metrics is not None
        px_per_unit = self._prop.get_size_in_points() * self._px_per_pt / font.units_per_EM
        gap = metrics["sTypoLineGap"]
        self._ascent = (metrics["sTypoAscender"] + gap / 2) * px_per_unit  # top to the first baseline [px]
        self._line_pitch = (metrics["sTypoAscender"] - metrics["sTypoDescender"] + gap) * px_per_unit
        self._glyphs: dict[str, tuple[FloatArray, NDArray[np.uint8]]] = {}
        self.patch = PathPatch(
            MplPath(np.zeros((0, 2))),
            transform=ScaledTranslation(x, y, ax.transAxes),  # type: ignore[arg-type]  # pixels from (x, y)
            facecolor=mpl.rcParams["text.color"],
            edgecolor="none",
            animated=True,
        )
        ax.add_artist(self.patch)

    def _glyph(self, char: str) -> tuple[FloatArray, NDArray[np.uint8]]:
        """The outline of ``char`` [px], its origin on the baseline at 0."""
        if char not in self._glyphs:
            from matplotlib.textpath import TextPath  # imported where used: matplotlib ~460 ms (python -X importtime)

            path = TextPath((0, 0), char, prop=self._prop)  # [pt]
            self._glyphs[char] = (np.asarray(path.vertices) * self._px_per_pt, np.asarray(path.codes, dtype=np.uint8))
        return self._glyphs[char]

    def set_text(self, text: str) -> None:
        from matplotlib.path import Path as MplPath  # imported where used: matplotlib ~460 ms (python -X importtime)

        vertices, codes = [np.zeros((0, 2))], [np.zeros(0, dtype=np.uint8)]
        for row, line in enumerate(text.split("\n")):
            baseline = -self._ascent - row * self._line_pitch
            for column, char in enumerate(line):
                if not char.isspace():
                    glyph, glyph_codes = self._glyph(char)
                    vertices.append(glyph + np.array((column * self._advance, baseline)))
                    codes.append(glyph_codes)
        self.patch.set_path(MplPath(np.concatenate(vertices), np.concatenate(codes)))


PALETTE_GREYS = 40
PALETTE_SHADES = 34
"""The frames' palette: besides the exact colours, 40 greys and 34 shades of each drawing colour."""
TRANSPARENT = 255
"""An index the palette leaves free: in a GIF frame, the pixels that stay as they were."""


class Palette:
    """The colours every frame is reduced to (at most 255) before it is written: white, black and
    the drawing colours exact, a grey ramp (text, axes, grid, surfaces) and each drawing colour
    faded into white in even steps (its antialiased edges).

    One fixed palette instead of an octree per frame: 4x quicker, the same indices for the same
    colours in every frame (the GIF stores only what changed), and the same indexed frames go to
    the GIF and, a quarter of the bytes of RGBA, to ffmpeg for the MP4.
    """

    def __init__(self) -> None:
        from PIL import Image  # imported where used: Pillow, only when drawing (python -X importtime)

        drawing = [LINK_COLOR, SURFACE_COLOR, FORCE_COLOR, TARGET_COLOR, TRAIL_COLOR, POINT_COLOR]
        exact = np.array([_rgb(c) for c in ["#ffffff", "#000000", *drawing]])
        greys = np.repeat(np.linspace(0.0, 255.0, PALETTE_GREYS)[:, None], 3, axis=1)
        white_share = np.linspace(0.0, 1.0, PALETTE_SHADES + 1, endpoint=False)[1:, None]
        shades = [_rgb(c) * (1.0 - white_share) + 255.0 * white_share for c in drawing]
        entries = np.concatenate([exact, greys, *shades]).round()
        # Pillow maps a colour to the entry nearest to it rounded down to a multiple of 4: leave out
        # the entries nearer to that than an exact colour itself, so that each maps to itself.
        keep = np.ones(len(entries), dtype=bool)
        for i, colour in enumerate(exact):
            distance = np.linalg.norm(entries - colour // 4 * 4, axis=1)
            keep &= (distance > distance[i]) | (np.arange(len(entries)) == i)
        self.rgb = entries[keep].astype(np.uint8)  # (colours, 3)
        assert len(self.rgb) <= TRANSPARENT
        self._image = Image.new("P", (1, 1))
        self._image.putpalette(self.rgb.tobytes())
        argb = np.zeros(256, dtype=np.uint32)
        argb[: len(self.rgb)] = 0xFF000000 | self.rgb.astype(np.uint32) @ np.array([1 << 16, 1 << 8, 1], np.uint32)
        self.ffmpeg = argb.tobytes()
        """ffmpeg's pal8 palette, sent after each frame: 256 opaque 0xAARRGGBB in native byte order."""

    def index(self, rgba: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """The palette index of every pixel of an RGBA image (rows, columns, 4)."""
        from PIL import Image  # imported where used: Pillow, only when drawing (python -X importtime)

        rgb = Image.frombytes("RGB", (rgba.shape[1], rgba.shape[0]), rgba, "raw", "RGBX")
        return np.asarray(rgb.quantize(palette=self._image, dither=Image.Dither.NONE))

    def image(self, index: NDArray[np.uint8]) -> Image.Image:
        """A "P" image of palette indices."""
        from PIL import Image  # imported where used: Pillow, only when drawing (python -X importtime)

        image = Image.fromarray(index, "P")
        image.putpalette(self.rgb.tobytes())
        return image


def _rgb(color: str) -> FloatArray:
    return np.array([int(color[i : i + 2], 16) for i in (1, 3, 5)], dtype=np.float64)


class GifWriter:
    """An animated GIF written as its frames come (palette indices): each frame after the first
    stored as the rectangle that changed, with the pixels in it that did not change transparent.

    That is what Pillow's ``save(save_all=True)`` makes of frames, in a third of its time: numpy
    compares the frames' indices, where Pillow converts whole frames to compare them. Pillow's
    GIF header and LZW encoder write the file.
    """

    def __init__(self, path: Path, palette: Palette, duration_ms: int) -> None:
        self._file = path.open("wb")
        self._palette = palette
        self._duration_ms = duration_ms
        self._previous: NDArray[np.uint8] | None = None

    def add(self, index: NDArray[np.uint8]) -> None:
        """Append a frame of palette indices (rows, columns)."""
        from PIL import GifImagePlugin  # imported where used: Pillow, only when drawing (python -X importtime)

        if self._previous is None:
            first = self._palette.image(index)
            self._file.write(b"".join(GifImagePlugin.getheader(first, info={"loop": 0})[0]))
            self._write(first, (0, 0))
        else:
            changed = index != self._previous
            rows, columns = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
            if rows.size == 0:  # the same picture: one transparent pixel keeps the frame and its time
                rows = columns = np.zeros(1, dtype=np.intp)
            box = np.s_[rows[0] : rows[-1] + 1, columns[0] : columns[-1] + 1]
            delta = self._palette.image(np.where(changed[box], index[box], np.uint8(TRANSPARENT)))
            self._write(delta, (int(columns[0]), int(rows[0])), transparency=TRANSPARENT)
        self._previous = index

    def _write(self, image: Image.Image, offset: tuple[int, int], **params: int) -> None:
        from PIL import GifImagePlugin  # imported where used: Pillow, only when drawing (python -X importtime)

        data = GifImagePlugin.getdata(image, offset, duration=self._duration_ms, **params)
        self._file.write(b"".join(data))

    def close(self, complete: bool = True) -> None:
        """Write the trailer and close the file; an incomplete GIF is removed instead."""
        if complete:
            self._file.write(b";")
        self._file.close()
        if not complete:
            Path(self._file.name).unlink(missing_ok=True)


def start_mp4(path: Path, interval_s: float) -> Any:
    """imageio-ffmpeg's writer (its bundled ffmpeg) of pal8 frames (indices, then ``Palette.ffmpeg``),
    primed; None without imageio-ffmpeg."""
    try:
        import imageio_ffmpeg  # imported where used: optional: the MP4 only (python -X importtime)
    except ImportError:
        return None
    writer = imageio_ffmpeg.write_frames(
        str(path),
        (int(FRAME_SIZE_IN[0] * FRAME_DPI), int(FRAME_SIZE_IN[1] * FRAME_DPI)),
        pix_fmt_in="pal8",
        fps=1.0 / interval_s,
        codec="libx264",
        pix_fmt_out="yuv420p",
        macro_block_size=1,
        quality=7,
        ffmpeg_log_level="error",
        # One thread each for the conversion to yuv420p and for x264: the least CPU beside the drawing.
        output_params=["-preset", "ultrafast", "-threads", "1", "-filter_threads", "1"],
    )
    writer.send(None)  # start the generator
    return writer
