"""Frames of a navigation episode: the track, true and estimated positions, outages, an error strip.

A small NumPy rasteriser (no drawing library needed for ``rgb_array``): the map is the
track seen from above in a local east-north plane (equirectangular about the track's
first point: a display projection, not a computation), with

* the track in grey, GNSS-outage epochs (fewer than 4 valid channels) in orange,
* the true path so far in green with the current true position as a green disc,
* the estimated path in red with the current estimate as a red disc,

and below it a strip of the horizontal error against time (red line, outages shaded,
scaled to the largest error so far). ``"human"`` shows the same frame in a matplotlib
window.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["TrackRenderer", "WIDTH", "HEIGHT"]

WIDTH, HEIGHT, STRIP = 480, 400, 80
_MARGIN = 12
_GREY, _GREEN, _RED, _ORANGE, _BLUE = (170, 170, 170), (0, 150, 0), (220, 0, 0), (255, 150, 0), (60, 60, 200)
_EARTH_R = 6.371e6


def _polyline(img: np.ndarray, x: np.ndarray, y: np.ndarray, color) -> None:
    """Draw a connected polyline through pixel coordinates x, y (float arrays)."""
    if len(x) == 0:
        return
    if len(x) == 1:
        _dots(img, x, y, color, 0)
        return
    dx, dy = np.diff(x), np.diff(y)
    count = np.ceil(np.maximum(np.abs(dx), np.abs(dy))).astype(int) + 1
    seg = np.repeat(np.arange(len(dx)), count)
    frac = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    frac = frac / np.repeat(np.maximum(count - 1, 1), count)
    _dots(img, x[seg] + frac * dx[seg], y[seg] + frac * dy[seg], color, 0)


def _dots(img: np.ndarray, x, y, color, radius: int) -> None:
    """Set the pixels within ``radius`` (a square) of each point; points outside are dropped."""
    h, w = img.shape[:2]
    xi = np.rint(np.asarray(x, dtype=float)).astype(int)
    yi = np.rint(np.asarray(y, dtype=float)).astype(int)
    for oy in range(-radius, radius + 1):
        for ox in range(-radius, radius + 1):
            if ox * ox + oy * oy > radius * radius + radius:
                continue
            px, py = xi + ox, yi + oy
            ok = (px >= 0) & (px < w) & (py >= 0) & (py < h)
            img[py[ok], px[ok]] = color


class TrackRenderer:
    """Draw frames of a :class:`~navsim.envs.navigation.NavigationEnv` episode."""

    def __init__(self, width: int = WIDTH, height: int = HEIGHT):
        self.width, self.height = int(width), int(height)
        self._fig = None
        self._base = None

    def reset(self, env) -> None:
        """Build the background (the track) for the env's scenario."""
        from navsim.track import track_frame

        track = env.sim.track
        s = np.linspace(0.0, track.length, 3000)
        frame = track_frame(track, s)
        self.lat0, self.lon0 = float(frame.lat[0]), float(frame.lon[0])
        self.coslat = math.cos(self.lat0)
        east, north = self._en(frame.lat, frame.lon)
        span = max(east.max() - east.min(), north.max() - north.min(), 1.0)
        usable_w = self.width - 2 * _MARGIN
        usable_h = self.height - STRIP - 2 * _MARGIN
        self.scale = min(usable_w, usable_h) / span  # pixels per metre
        self.cx = 0.5 * (east.max() + east.min())
        self.cy = 0.5 * (north.max() + north.min())
        img = np.full((self.height, self.width, 3), 255, dtype=np.uint8)
        img[self.height - STRIP:, :] = 245
        img[self.height - STRIP, :] = 200
        px, py = self._px(east, north)
        _polyline(img, px, py, _GREY)
        _dots(img, px, py, _GREY, 1)
        self._base = img

    def _en(self, lat, lon):
        lat, lon = np.asarray(lat, float), np.asarray(lon, float)
        return (lon - self.lon0) * _EARTH_R * self.coslat, (lat - self.lat0) * _EARTH_R

    def _px(self, east, north):
        x = 0.5 * self.width + (east - self.cx) * self.scale
        y = 0.5 * (self.height - STRIP) - (north - self.cy) * self.scale
        return x, y

    def frame(self, env) -> np.ndarray:
        """The (H, W, 3) uint8 frame of the episode so far."""
        if self._base is None:
            self.reset(env)
        img = self._base.copy()
        tape = getattr(env, "tape", None)
        k = max(int(getattr(env, "_k", 0)), 0)
        if tape is None or k == 0:
            if env._pc is not None:
                row = env._pc.truth[min(env._i, env._pc.n - 1)]
                _dots(img, *self._px(*self._en(row[0], row[1])), _GREEN, 3)
            return img
        n = min(k, tape.n)
        stride = max(1, n // 2000)
        idx = np.arange(0, n, stride)
        # outage epochs: fewer than 4 valid channels
        if tape.gnss_t:
            g_t = np.concatenate(tape.gnss_t)
            g_nv = np.concatenate(tape.gnss_n_valid)
            dt = env.scenario.timing.nav_period_s
            g_k = np.rint(g_t / dt).astype(int) - 1
            out = g_k[(g_nv < 4) & (g_k < n)]
            if out.size:
                _dots(img, *self._px(*self._en(tape.lat[out], tape.lon[out])), _ORANGE, 2)
        tx, ty = self._px(*self._en(tape.lat[idx], tape.lon[idx]))
        _polyline(img, tx, ty, _GREEN)
        est = np.asarray(tape.actions[: n], dtype=float) * env.action_scale  # actions are normalised
        fin = np.all(np.isfinite(est[:, :2]), axis=1)
        ex, ey = self._px(*self._en(est[idx, 0], est[idx, 1]))
        ok = fin[idx]
        _polyline(img, ex[ok], ey[ok], _RED)
        _dots(img, tx[-1:], ty[-1:], _GREEN, 3)
        if ok[-1]:
            _dots(img, ex[-1:], ey[-1:], _RED, 3)
        # error strip: horizontal error (m) against time
        r = 6.371e6
        d_n = (est[:, 0] - tape.lat[:n]) * r
        d_e = (est[:, 1] - tape.lon[:n]) * r * np.cos(tape.lat[:n])
        err = np.hypot(d_e, d_n)
        err = np.where(np.isfinite(err), err, np.nan)
        top = np.nanmax(err) if np.any(np.isfinite(err)) else 1.0
        top = max(float(top), 1.0)
        x = _MARGIN + (idx / max(tape.n - 1, 1)) * (self.width - 2 * _MARGIN)
        y0 = self.height - 6
        y = y0 - np.nan_to_num(err[idx], nan=top) / top * (STRIP - 12)
        if tape.gnss_t:
            g_x = _MARGIN + (out / max(tape.n - 1, 1)) * (self.width - 2 * _MARGIN) if out.size else np.zeros(0)
            for gx in np.unique(np.rint(g_x).astype(int)):
                img[self.height - STRIP + 1:, max(gx - 1, 0):gx + 2] = (255, 225, 180)
        img[y0, _MARGIN:self.width - _MARGIN] = _BLUE
        _polyline(img, x, y, _RED)
        return img

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
