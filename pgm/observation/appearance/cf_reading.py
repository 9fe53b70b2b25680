"""How the particles read the correlation filter's response: one search window per frame
(and a second where the particles split into two clouds), one response map per scale
level (and per turned angle), each particle's response read bilinearly in position and
linearly in log-scale (:class:`~pgm.observation.appearance.correlation.
CorrelationFilterLikelihood`)."""

from __future__ import annotations

import numpy as np

from pgm.core.boxes import mean_box_size
from pgm.core.frame import FrameContext

from .cf_features import _one_cloud

__all__ = ["ResponseReading"]


class ResponseReading:
    """The response maps of a frame and the particles' reading of them (a mixin of
    :class:`~pgm.observation.appearance.correlation.CorrelationFilterLikelihood`)."""

    def _window(self, ctx: FrameContext, centre, levels, angle: float, key):
        """Response maps of one window turned by ``angle``: one per scale level, and with
        an angle component two more at ``angle ± angle_step`` and the middle scale (None
        without); cached on the frame."""
        def make():
            maps = np.stack([self._response(self._spectrum(ctx, centre, s, angle))
                             for s in levels]) / self.peak
            if self.angle_index is None:
                return maps, None
            mid = float(levels[len(levels) // 2])
            turned = np.stack([self._response(self._spectrum(ctx, centre, mid, a))
                               for a in (angle - self.angle_step, angle + self.angle_step)])
            return maps, turned / self.peak

        return self._cached(ctx, ("cf-window",) + key, make)

    def _maps(self, x: np.ndarray, ctx: FrameContext):
        """This frame's first window: its centre (the particles' mean), scale levels
        (around their mean scale) and maps (computed at the first call in a frame and
        cached on it)."""
        def make():
            self._check_camera(ctx)
            b = self.boxes(x)
            base = mean_box_size(b) / self.ref_scale
            levels = base * self.scale_step ** (np.arange(self.scales) - self.scales // 2)
            centre = b[:, :2].mean(axis=0)
            quarter = self.ref_size * base / 4
            if (self.windows > 1 and self.opened(ctx) is not None
                    and not _one_cloud(b[:, :2], centre, quarter)):
                centre = self._next_centre(b[:, :2], quarter)
            angle = 0.0 if self.angle_index is None else float(x[:, self.angle_index].mean())
            return centre, levels, angle, self._window(ctx, centre, levels, angle, ())

        return self._cached(ctx, ("cf-response",), make)

    def relative_response(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N,)`` response at each particle, in units of the typical peak.

        The first window is centred on the particles' mean. With ``windows > 1`` in a
        frame where a proposal put particles near peaks of the re-detection's scan
        (:meth:`detect`, :meth:`open_windows_at`), and unless
        nine in ten particles lie within a quarter window of the mean (one cloud, a few
        stragglers: the usual case; otherwise a proposal put some near a far-away peak),
        each window is centred on a mode of the particles not yet read — the one with
        the most of them within a quarter window — and reads those within a quarter
        window of its centre, so every particle is read near the middle of a window,
        where the maps are comparable; the windows after the first open only at
        particles within a quarter window of a proposed peak; at most ``windows``
        windows, the last reading every particle inside it, and a particle outside them
        all scores ``floor``. In any other frame every particle is read in the one
        window at the mean, as with ``windows=1``: a particle the transition's jumps
        carried outside it scores ``floor`` (read in windows of their own, such
        stragglers took the posterior to a distractor on David, AUC 0.550 against 0.634
        over eight seeds)."""
        self.require_model()
        centre, levels, angle, maps = self._maps(x, ctx)
        b = self.boxes(x)
        angles = (np.zeros(len(b)) if self.angle_index is None
                  else np.asarray(x[:, self.angle_index], float))
        quarter = self.ref_size * float(levels[len(levels) // 2]) / 4
        peaks = self.opened(ctx) if self.windows > 1 else None
        if peaks is None or _one_cloud(b[:, :2], b[:, :2].mean(axis=0), quarter):
            return self._read(maps, levels, angle, centre, b, angles)[0]
        out = np.full(len(b), self.floor)
        todo = np.arange(len(b))
        for k in range(self.windows):
            if k > 0:
                near = np.any(np.all(np.abs(b[todo, None, :2] - peaks[None]) <= quarter,
                                     axis=2), axis=1)
                if not near.any():
                    break
                centre = self._next_centre(b[todo[near], :2], quarter)
                maps = self._window(ctx, centre, levels, angle,
                                    (round(centre[0], 3), round(centre[1], 3)))
            val, inside = self._read(maps, levels, angle, centre, b[todo], angles[todo])
            if k < self.windows - 1:
                inside &= np.all(np.abs(b[todo, :2] - centre) <= quarter, axis=1)
            out[todo[inside]] = val[inside]
            todo = todo[~inside]
            if todo.size == 0:
                break
        return out

    @staticmethod
    def _next_centre(xy: np.ndarray, quarter: np.ndarray) -> np.ndarray:
        """Among points ``xy``, the one with the most others within ``quarter`` of it."""
        d = np.abs(xy[:, None, :] - xy[None, :, :]) <= quarter
        return xy[int(np.argmax(np.sum(d.all(axis=2), axis=1)))]

    @staticmethod
    def _sample(maps: np.ndarray, which, centre, b, step, angle):
        """Bilinear reading of the maps ``maps[which]`` (``which``: one index per box, or
        one for all) of windows turned by ``angle`` (per box or one) with cells ``step``
        (image px, per box or one) at the boxes' centres; and whether each lies in its
        window."""
        _, th, tw = maps.shape
        c, s = np.cos(angle), np.sin(angle)
        dx, dy = b[:, 0] - centre[0], b[:, 1] - centre[1]
        u = (c * dx + s * dy) / step[..., 0] + (tw - 1) / 2
        v = (-s * dx + c * dy) / step[..., 1] + (th - 1) / 2
        inside = (u >= 0) & (u <= tw - 1) & (v >= 0) & (v <= th - 1)
        u0 = np.clip(np.floor(u).astype(np.intp), 0, tw - 2)
        v0 = np.clip(np.floor(v).astype(np.intp), 0, th - 2)
        fu, fv = np.clip(u - u0, 0, 1), np.clip(v - v0, 0, 1)
        val = ((1 - fv) * ((1 - fu) * maps[which, v0, u0] + fu * maps[which, v0, u0 + 1])
               + fv * ((1 - fu) * maps[which, v0 + 1, u0]
                       + fu * maps[which, v0 + 1, u0 + 1]))
        return val, inside

    def _read(self, window, levels, angle, centre, b, angles) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear (position), linear (log-scale) and, with an angle component, linear
        (angle) reading of a window's maps at the boxes ``b`` turned by ``angles``:
        values and whether each box's centre lies in the window."""
        maps, turned = window
        n_lev, th, tw = maps.shape
        scale = np.sqrt(np.maximum(b[:, 2] * b[:, 3], 1e-12)) / self.ref_scale
        if n_lev > 1:
            pos = (np.log(scale) - np.log(levels[0])) / np.log(self.scale_step)
            pos = np.clip(pos, 0, n_lev - 1)
        else:
            pos = np.zeros(len(b))
        l0 = np.minimum(np.floor(pos).astype(np.intp), n_lev - 1)
        l1 = np.minimum(l0 + 1, n_lev - 1)
        fl = pos - l0
        out = np.zeros(len(b))
        inside_all = np.ones(len(b), dtype=bool)
        cells = np.array(self.shape, dtype=float)
        for lev, wgt in ((l0, 1 - fl), (l1, fl)):
            # particle centre in the level's window: template px
            step = self.ref_size[None, :] * levels[lev][:, None] / cells[None]
            val, inside = self._sample(maps, lev, centre, b, step, angle)
            out += wgt * np.where(inside, val, self.floor)
            inside_all &= inside | (wgt == 0)
        if turned is not None:  # the change of response with the particle's own angle
            step = self.ref_size * float(levels[n_lev // 2]) / cells
            mid, ok = self._sample(maps, n_lev // 2, centre, b, step, angle)
            t = np.clip((angles - angle) / self.angle_step, -1.0, 1.0)
            side = (t >= 0).astype(np.intp)  # turned[0]: angle - step, turned[1]: + step
            val, ins = self._sample(turned, side, centre, b, step,
                                    angle + (2 * side - 1) * self.angle_step)
            out += np.where(ok & ins, np.abs(t) * (val - mid), 0.0)
        return out, inside_all
