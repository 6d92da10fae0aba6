"""Frames of a navsim episode: the track map with axes and scale, a time strip, a time stamp.

Every env id renders the same kind of frame (``render_mode="rgb_array"``: an
``(HEIGHT, WIDTH, 3)`` uint8 array; ``"human"``: the same frame in a matplotlib window):

* a title line: the simulated time stamp ``t = 12.34 s / 60 s`` and the scenario;
* the map: the track seen from above in a local east-north plane about the track's
  first point (equirectangular with a spherical radius of 6371 km: a display projection,
  not a computation; one scale on both axes), framed by axes with ticks labelled in m or
  km (``east, km`` / ``north, km``) and a scale bar; the track in grey, GNSS-outage epochs
  (fewer than 4 valid channels) in orange, the true path so far in green with the current
  true position as a green disc, the estimated path in red with the current estimate as
  a red disc, stations (the driving task) as blue ticks;
* the strip: a quantity against time over the whole episode (0 .. duration on the time
  axis, labelled in s), scaled to a round value above its largest value so far, the
  y axis labelled with the quantity and its unit: the horizontal error (m) of the
  estimate for the navigation and adaptive-filtering envs, the true and estimated speed
  (m/s) for the driving task; outage epochs shaded;
* a status line the env supplies (noise factors, next station, lateness, ...).

Frames come at the env's real time rate: each env's ``metadata["render_fps"]`` is one
over the simulated time of one step (``1 / nav_period_s`` for the navigation envs,
``1 / decision_period_s`` for the two tasks), so a recorded video
(:class:`gymnasium.wrappers.RecordVideo`, one frame per step) lasts as long as the
simulated episode; pass ``fps=`` to ``RecordVideo`` for a time lapse.

The geometry is drawn by a small NumPy rasteriser; text by Pillow (a dependency of the
``gym`` extra) with its default font.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Protocol, Sequence, cast

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:  # type hints only
    from navsim.scenario import Scenario

    from .chunks import EpisodeTape
    from .navigation import NavigationEnv

RGB = tuple[int, int, int]
TextItem = tuple[float, float, str, str]
"""``(x, y, text, align)``: a label at pixel x, top y, align "l", "r" or "c"."""


class RenderableEnv(Protocol):
    """What the renderer reads of an env: its simulator (``sim.track``), its scenario
    (timing, name), ``render_mode`` and ``metadata["render_fps"]``; an env with a
    ``render_view()`` method is drawn from that view, else as a NavigationEnv."""

    @property
    def sim(self) -> Any: ...

    @property
    def scenario(self) -> Scenario: ...

    @property
    def render_mode(self) -> str | None: ...

    @property
    def metadata(self) -> dict[str, Any]: ...

__all__ = ["TrackRenderer", "FrameView", "navigation_view", "nice_step", "WIDTH", "HEIGHT"]

WIDTH, HEIGHT = 560, 480
_TOP = 24  # title line
_LEFT, _RIGHT = 60, 14
_MAP_BOTTOM = 318  # the map box spans _TOP + 4 .. _MAP_BOTTOM
_STRIP_TOP, _STRIP_BOTTOM = 358, 452  # the strip box
_GREY, _GREEN, _RED, _ORANGE, _BLUE = (170, 170, 170), (0, 150, 0), (220, 0, 0), (255, 150, 0), (60, 60, 200)
_AXIS, _TEXT, _SHADE = (90, 90, 90), (30, 30, 30), (255, 225, 180)
_EARTH_R = 6.371e6


@dataclass
class FrameView:
    """What one frame shows (built by the env; arrays may be empty).

    ``truth_lat/lon``, ``est_lat/lon`` (rad): paths so far (the last point is the current
    one); ``outage_lat/lon``: true positions at outage epochs; ``strip_t`` (s) with
    ``strip_series`` ``[(values, rgb), ...]`` against it; ``outage_t`` (s): outage epochs, each
    shading the ``outage_dt`` (s, the GNSS period) after it in the strip; ``marks_lat/lon``: stations.
    """

    t_s: float
    duration_s: float
    truth_lat: np.ndarray
    truth_lon: np.ndarray
    est_lat: np.ndarray = field(default_factory=lambda: np.zeros(0))
    est_lon: np.ndarray = field(default_factory=lambda: np.zeros(0))
    outage_lat: np.ndarray = field(default_factory=lambda: np.zeros(0))
    outage_lon: np.ndarray = field(default_factory=lambda: np.zeros(0))
    strip_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    strip_series: list = field(default_factory=list)
    strip_label: str = "horizontal error, m"
    outage_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    outage_dt: float = 0.0
    marks_lat: np.ndarray = field(default_factory=lambda: np.zeros(0))
    marks_lon: np.ndarray = field(default_factory=lambda: np.zeros(0))
    status: str = ""


def nice_step(span: float, target: int = 5) -> float:
    """A round tick step (1, 2 or 5 x 10^k) giving about ``target`` ticks over ``span``."""
    if not (span > 0 and math.isfinite(span)):
        return 1.0
    return _nice_ceiling(span / target, 1e-9)


def _nice_ceiling(x: float, tol: float = 1e-12) -> float:
    """The smallest 1, 2 or 5 x 10^k >= x (x > 0; to a relative ``tol``)."""
    mag = 10.0 ** math.floor(math.log10(x))
    for m in (1.0, 2.0, 5.0, 10.0):
        if x <= m * mag * (1 + tol):
            return m * mag
    return 10.0 * mag  # pragma: no cover


def _nice_floor(x: float) -> float:
    """The largest 1, 2 or 5 x 10^k <= x (x > 0)."""
    mag = 10.0 ** math.floor(math.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * mag <= x * (1 + 1e-12):
            return m * mag
    return mag  # pragma: no cover


def _fmt(x: float, step: float) -> str:
    digits = max(0, -int(math.floor(math.log10(step) + 1e-9))) if step < 1 else 0
    return f"{x:.{digits}f}"


def _polyline(img: np.ndarray, x: np.ndarray, y: np.ndarray, color: RGB) -> None:
    """Draw a connected polyline through pixel coordinates x, y (float arrays)."""
    if len(x) == 0:
        return
    if len(x) == 1:
        _dots(img, x, y, color, 0)
        return
    dx, dy = np.diff(x), np.diff(y)
    count = np.ceil(np.minimum(np.maximum(np.abs(dx), np.abs(dy)), 4 * max(img.shape))).astype(int) + 1
    seg = np.repeat(np.arange(len(dx)), count)
    frac = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    frac = frac / np.repeat(np.maximum(count - 1, 1), count)
    _dots(img, x[seg] + frac * dx[seg], y[seg] + frac * dy[seg], color, 0)


def _dots(img: np.ndarray, x: ArrayLike, y: ArrayLike, color: RGB, radius: int,
          box: tuple[int, int, int, int] | None = None) -> None:
    """Set the pixels within ``radius`` of each point; points outside the image (or ``box``
    = (x0, y0, x1, y1)) are dropped."""
    h, w = img.shape[:2]
    x0, y0, x1, y1 = box if box is not None else (0, 0, w - 1, h - 1)
    xf = np.asarray(x, dtype=float)
    yf = np.asarray(y, dtype=float)
    ok = np.isfinite(xf) & np.isfinite(yf)
    xi = np.rint(xf[ok]).astype(int)
    yi = np.rint(yf[ok]).astype(int)
    for oy in range(-radius, radius + 1):
        for ox in range(-radius, radius + 1):
            if ox * ox + oy * oy > radius * radius + radius:
                continue
            px, py = xi + ox, yi + oy
            inside = (px >= x0) & (px <= x1) & (py >= y0) & (py <= y1)
            img[py[inside], px[inside]] = color


@lru_cache(maxsize=1)
def _font() -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=11)
    except TypeError:  # pragma: no cover - Pillow < 10.1: the bitmap font
        return ImageFont.load_default()


@lru_cache(maxsize=1024)
def _text_mask(text: str) -> np.ndarray:
    """The coverage (0..1, float32) of ``text`` in the default font, as a small (h, w) array."""
    from PIL import Image, ImageDraw

    font = _font()
    left, top, right, bottom = ImageDraw.Draw(Image.new("L", (1, 1))).textbbox((0, 0), text, font=font)
    mask = Image.new("L", (max(int(right) + 1, 1), max(int(bottom) + 1, 1)), 0)
    ImageDraw.Draw(mask).text((0, 0), text, fill=255, font=font)
    return np.asarray(mask, dtype=np.float32) / 255.0


def _draw_text(img: np.ndarray, items: Sequence[TextItem]) -> None:
    """Draw ``(x, y, text, align)`` items, align in {"l", "r", "c"} horizontally, y the top."""
    h, w = img.shape[:2]
    for x, y, text, align in items:
        mask = _text_mask(text)
        mh, mw = mask.shape
        x0 = int(round(x - mw if align == "r" else x - 0.5 * mw if align == "c" else x))
        y0 = int(round(y))
        xa, ya, xb, yb = max(x0, 0), max(y0, 0), min(x0 + mw, w), min(y0 + mh, h)
        if xa >= xb or ya >= yb:
            continue
        a = mask[ya - y0:yb - y0, xa - x0:xb - x0, None]
        region = img[ya:yb, xa:xb].astype(np.float32)
        img[ya:yb, xa:xb] = np.rint(region * (1.0 - a) + np.asarray(_TEXT, np.float32) * a).astype(np.uint8)


class TrackRenderer:
    """Draw frames of a navsim env episode (any env with a ``sim``; see :func:`view_of`)."""

    def __init__(self, width: int = WIDTH, height: int = HEIGHT):
        self.width, self.height = int(width), int(height)
        self._fig: Any = None  # matplotlib figure of the "human" mode
        self._image: Any = None
        self._base: np.ndarray | None = None
        self.map_box = (_LEFT, _TOP + 4, self.width - _RIGHT, _MAP_BOTTOM)
        self.strip_box = (_LEFT, _STRIP_TOP, self.width - _RIGHT, _STRIP_BOTTOM)

    # ------------------------------------------------------------------ background
    def reset(self, env: RenderableEnv) -> None:
        """Build the background (track, axes, ticks, scale bar) for the env's scenario."""
        from navsim.track import track_frame

        track = env.sim.track
        s = np.linspace(0.0, track.length, 3000)
        frame = track_frame(track, s)
        self.lat0, self.lon0 = float(frame.lat[0]), float(frame.lon[0])
        self.coslat = math.cos(self.lat0)
        east, north = self._en(frame.lat, frame.lon)
        x0, y0, x1, y1 = self.map_box
        span_e = max(float(east.max() - east.min()), 1.0)
        span_n = max(float(north.max() - north.min()), 1.0)
        self.scale = 0.92 * min((x1 - x0) / span_e, (y1 - y0) / span_n)  # pixels per metre
        self.cx = 0.5 * (east.max() + east.min())
        self.cy = 0.5 * (north.max() + north.min())
        img = np.full((self.height, self.width, 3), 255, dtype=np.uint8)
        px, py = self._px(east, north)
        _polyline(img, px, py, _GREY)
        _dots(img, px, py, _GREY, 1, box=self.map_box)
        texts = self._map_axes(img)
        self._strip_frame(img)
        duration = float(env.scenario.timing.duration_s)
        self.duration = duration
        step = nice_step(duration)
        sx0, sy0, sx1, sy1 = self.strip_box
        for tick in np.arange(0.0, duration * (1 + 1e-9), step).tolist():
            x = sx0 + tick / duration * (sx1 - sx0)
            img[sy1:sy1 + 4, int(round(x))] = _AXIS
            texts.append((x, sy1 + 5, _fmt(tick, step), "c"))
        texts.append((sx1, sy1 + 17, "t, s", "r"))
        _draw_text(img, texts)
        self._base = img

    def _map_axes(self, img: np.ndarray) -> list[TextItem]:
        x0, y0, x1, y1 = self.map_box
        img[y0, x0:x1 + 1] = img[y1, x0:x1 + 1] = _AXIS
        img[y0:y1 + 1, x0] = img[y0:y1 + 1, x1] = _AXIS
        # visible east/north ranges (m, about the track's first point)
        e_lo, e_hi = self.cx + (x0 - 0.5 * (x0 + x1)) / self.scale, self.cx + (x1 - 0.5 * (x0 + x1)) / self.scale
        n_lo, n_hi = self.cy - (y1 - 0.5 * (y0 + y1)) / self.scale, self.cy - (y0 - 0.5 * (y0 + y1)) / self.scale
        span = max(e_hi - e_lo, n_hi - n_lo)
        km = span >= 2000.0
        unit, factor = ("km", 1e-3) if km else ("m", 1.0)
        self.unit, self.factor = unit, factor
        step = nice_step(span * factor, 5) / factor  # metres
        texts: list[TextItem] = []
        for tick in np.arange(math.ceil(e_lo / step) * step, e_hi, step):
            x = int(round(self._px(tick, 0.0)[0]))
            img[y1:y1 + 4, x] = _AXIS
            texts.append((x, y1 + 5, _fmt(tick * factor, step * factor), "c"))
        for tick in np.arange(math.ceil(n_lo / step) * step, n_hi, step):
            y = int(round(self._px(0.0, tick)[1]))
            img[y, x0 - 4:x0] = _AXIS
            texts.append((x0 - 6, y - 6, _fmt(tick * factor, step * factor), "r"))
        texts.append((x1, y1 + 17, f"east, {unit}", "r"))
        texts.append((x0 + 4, y0 + 2, f"north, {unit}", "l"))
        # scale bar: the largest round length (1, 2, 5 x 10^k m) within a quarter of the box width
        bar = _nice_floor(0.25 * (x1 - x0) / self.scale)
        bar_px = bar * self.scale
        bx, by = x0 + 10, y1 - 10
        img[by - 1:by + 1, bx:bx + int(round(bar_px)) + 1] = _TEXT
        img[by - 4:by + 3, bx] = img[by - 4:by + 3, bx + int(round(bar_px))] = _TEXT
        label = f"{bar * 1e-3:g} km" if bar >= 1000 else f"{bar:g} m"
        texts.append((bx + 0.5 * bar_px, by - 16, label, "c"))
        self.scale_bar_m = bar
        return texts

    def _strip_frame(self, img: np.ndarray) -> None:
        x0, y0, x1, y1 = self.strip_box
        img[y0, x0:x1 + 1] = img[y1, x0:x1 + 1] = _AXIS
        img[y0:y1 + 1, x0] = img[y0:y1 + 1, x1] = _AXIS

    def _en(self, lat: ArrayLike, lon: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        la, lo = np.asarray(lat, float), np.asarray(lon, float)
        return (lo - self.lon0) * _EARTH_R * self.coslat, (la - self.lat0) * _EARTH_R

    def _px(self, east: ArrayLike, north: ArrayLike) -> tuple[Any, Any]:  # arrays, 0-d for scalars
        x0, y0, x1, y1 = self.map_box
        x = 0.5 * (x0 + x1) + (np.asarray(east) - self.cx) * self.scale
        y = 0.5 * (y0 + y1) - (np.asarray(north) - self.cy) * self.scale
        return x, y

    # ------------------------------------------------------------------ frames
    def frame(self, env: RenderableEnv) -> np.ndarray:
        """The (H, W, 3) uint8 frame of the episode so far."""
        if self._base is None:
            self.reset(env)
        assert self._base is not None  # built by reset
        view = view_of(env)
        img = self._base.copy()
        box = self.map_box
        texts: list[TextItem] = [(_LEFT, 5, f"t = {view.t_s:.2f} s / {view.duration_s:g} s", "l"),
                 (self.width - _RIGHT, 5, str(env.scenario.name), "r")]
        if view.outage_lat.size:
            _dots(img, *self._px(*self._en(view.outage_lat, view.outage_lon)), _ORANGE, 2, box=box)
        if view.marks_lat.size:
            mx, my = self._px(*self._en(view.marks_lat, view.marks_lon))
            for dy in range(-6, 7):
                _dots(img, mx, my + dy, _BLUE, 0, box=box)
        inside = self._clip
        if view.truth_lat.size:
            tx, ty = self._px(*self._en(view.truth_lat, view.truth_lon))
            _polyline(img, *inside(tx, ty), _GREEN)
        if view.est_lat.size:
            ex, ey = self._px(*self._en(view.est_lat, view.est_lon))
            _polyline(img, *inside(ex, ey), _RED)
            _dots(img, ex[-1:], ey[-1:], _RED, 3, box=box)
        if view.truth_lat.size:
            _dots(img, tx[-1:], ty[-1:], _GREEN, 3, box=box)
        texts += self._strip(img, view)
        if view.status:
            texts.append((_LEFT, _MAP_BOTTOM + 19, view.status, "l"))
        _draw_text(img, texts)
        return img

    def _clip(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clamp a path's pixels to the map box (a path leaving the box runs along its edge)."""
        x0, y0, x1, y1 = self.map_box
        ok = np.isfinite(x) & np.isfinite(y)
        return np.clip(x[ok], x0 + 1, x1 - 1), np.clip(y[ok], y0 + 1, y1 - 1)

    def _strip(self, img: np.ndarray, view: FrameView) -> list[TextItem]:
        x0, y0, x1, y1 = self.strip_box
        duration = max(view.duration_s, 1e-9)
        texts: list[TextItem] = []
        if view.outage_t.size:  # each outage epoch shades the GNSS period after it (at least 3 px)
            half = max(1, int(math.ceil(0.5 * view.outage_dt / duration * (x1 - x0))))
            centre = x0 + (view.outage_t + 0.5 * view.outage_dt) / duration * (x1 - x0)
            for x in np.unique(np.rint(centre).astype(int)):
                img[y0 + 1:y1, max(x - half, x0 + 1):min(x + half + 1, x1)] = _SHADE
        top = 0.0
        for values, _ in view.strip_series:
            v = np.asarray(values, dtype=float)
            v = v[np.isfinite(v)]
            if v.size:
                top = max(top, float(np.max(np.abs(v))))
        top = _nice_ceiling(top) if top > 0 else 1.0
        t = np.asarray(view.strip_t, dtype=float)
        x = x0 + t / duration * (x1 - x0)
        for values, color in view.strip_series:
            v = np.asarray(values, dtype=float)
            ok = np.isfinite(v)
            y = y1 - np.clip(v[ok], 0.0, top) / top * (y1 - y0 - 4)
            _polyline(img, x[ok], y, color)
        for frac in (0.0, 0.5, 1.0):
            y_tick = int(round(y1 - frac * (y1 - y0 - 4)))
            img[y_tick, x0 - 4:x0] = _AXIS
            texts.append((x0 - 6, y_tick - 6, _fmt(frac * top, 0.5 * top), "r"))
        texts.append((x0 + 4, y0 + 2, view.strip_label, "l"))
        return texts

    # ------------------------------------------------------------------ human mode
    def show(self, frame: np.ndarray, fps: float) -> None:
        """Show a frame in a matplotlib window (the "human" mode)."""
        try:
            import matplotlib.pyplot as plt
        except ImportError:  # pragma: no cover
            from navsim.errors import DependencyNotInstalled

            raise DependencyNotInstalled("matplotlib", "plot") from None
        if self._fig is None:
            plt.ion()
            self._fig, ax = plt.subplots(figsize=(self.width / 100, self.height / 100))
            ax.set_axis_off()
            self._image = ax.imshow(frame)
        else:
            self._image.set_data(frame)
        self._fig.canvas.draw_idle()
        self._fig.canvas.flush_events()

    def close(self) -> None:
        if self._fig is not None:
            import matplotlib.pyplot as plt

            plt.close(self._fig)
            self._fig = None


def horizontal_error(est_lat: ArrayLike, est_lon: ArrayLike, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """Horizontal distance (m) for display: spherical radius 6371 km, local-level."""
    d_n = (np.asarray(est_lat) - lat) * _EARTH_R
    d_e = (np.asarray(est_lon) - lon) * _EARTH_R * np.cos(lat)
    err = np.hypot(d_e, d_n)
    return np.where(np.isfinite(err), err, np.nan)


def tape_view(tape: EpisodeTape, k: int, actions: Sequence[ArrayLike], scale: ArrayLike | float, dt: float,
              duration_s: float, gnss_period_s: float,
              strip: str = "error", status: str = "", stride_max: int = 2000) -> FrameView:
    """The view of the first k steps of an episode tape (truth per step, GNSS per epoch).

    ``actions``: the per-step solutions (a sequence of 9 numbers each) times ``scale``
    (the physical solution); only the drawn rows (at most ``stride_max`` + 1) are read.
    ``strip``: "error" (horizontal error of the estimate, m) or "speed" (true and
    estimated speed, m/s).
    """
    n = min(k, tape.n, len(actions))
    stride = max(1, n // stride_max)
    idx: np.ndarray = np.arange(0, n, stride)
    if n and idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    out_k = np.zeros(0, dtype=int)
    if tape.gnss_t:
        g_t = np.concatenate(tape.gnss_t)
        g_nv = np.concatenate(tape.gnss_n_valid)
        g_k = np.rint(g_t / dt).astype(int) - 1
        out_k = g_k[(g_nv < 4) & (g_k < n) & (g_k >= 0)]
    lat, lon = tape.lat[idx], tape.lon[idx]
    e = np.array([actions[i] for i in idx.tolist()], dtype=float).reshape(-1, 9) * scale
    fin = np.all(np.isfinite(e[:, :2]), axis=1)
    if strip == "speed":
        series = [(np.linalg.norm(tape.velocity_n[idx], axis=1), _GREEN), (np.linalg.norm(e[:, 3:6], axis=1), _RED)]
        label = "speed, m/s (true green, estimated red)"
    else:
        series = [(horizontal_error(e[:, 0], e[:, 1], lat, lon), _RED)]
        label = "horizontal error, m"
    return FrameView(t_s=n * dt, duration_s=duration_s, truth_lat=lat, truth_lon=lon,
                     est_lat=e[fin, 0], est_lon=e[fin, 1], outage_lat=tape.lat[out_k], outage_lon=tape.lon[out_k],
                     strip_t=(idx + 1) * dt, strip_series=series, strip_label=label, outage_t=(out_k + 1) * dt,
                     outage_dt=gnss_period_s, status=status)


def navigation_view(env: NavigationEnv) -> FrameView:
    """The view of a :class:`~navsim.envs.navigation.NavigationEnv` episode so far."""
    dt = env.scenario.timing.nav_period_s
    duration = env.scenario.timing.duration_s
    k = max(int(getattr(env, "_k", 0)), 0)
    tape = getattr(env, "tape", None)
    if tape is None or k == 0:
        lat = lon = np.zeros(0)
        if env._pc is not None:
            row = env._pc.truth[min(env._i, env._pc.n - 1)]
            lat, lon = np.array([row[0]]), np.array([row[1]])
        return FrameView(t_s=k * dt, duration_s=duration, truth_lat=lat, truth_lon=lon,
                         status="" if tape is not None else "score=False: no episode tape, current position only")
    # the actions are normalised
    return tape_view(tape, k, tape.actions, env.action_scale, dt, duration, env.scenario.timing.gnss_period_s)


def view_of(env: RenderableEnv) -> FrameView:
    """The env's own ``render_view()`` if it has one, else the navigation view."""
    own = getattr(env, "render_view", None)
    return own() if callable(own) else navigation_view(cast("NavigationEnv", env))


def render_env(env: RenderableEnv, renderer: TrackRenderer | None) -> tuple[np.ndarray | None, TrackRenderer | None]:
    """The common ``render()`` of the navsim envs; returns (result, renderer)."""
    import gymnasium as gym

    if env.render_mode is None:
        gym.logger.warn(f"{type(env).__name__}.render() without a render_mode: pass render_mode='rgb_array' to make().")
        return None, renderer
    if renderer is None:
        renderer = TrackRenderer()
        if getattr(env, "_k", -1) >= 0:
            renderer.reset(env)
    frame = renderer.frame(env)
    if env.render_mode == "human":
        renderer.show(frame, env.metadata["render_fps"])
        return None, renderer
    return frame, renderer


class EnvRendering:
    """``render()`` and ``close()`` of the navsim envs, written once (a base listed before
    ``gym.Env``): the frame through :func:`render_env`, the renderer kept in ``_renderer``
    (the env's ``reset`` restarts it), the window released by ``close``."""

    _renderer: TrackRenderer | None = None

    def render(self) -> np.ndarray | None:
        """"rgb_array": an (H, W, 3) uint8 frame; "human": the frame in a window (:mod:`navsim.envs.render`)."""
        frame, self._renderer = render_env(cast("RenderableEnv", self), self._renderer)
        return frame

    def close(self) -> None:
        """Release the window (if any); harmless to call more than once."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()  # type: ignore[misc]  # gym.Env.close, next in the env's bases
