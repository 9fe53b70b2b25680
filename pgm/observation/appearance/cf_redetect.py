"""The correlation filter's re-detection scan: the long-term filter correlated with the
whole frame, its peaks where the object may be (:class:`~pgm.observation.appearance.
correlation.CorrelationFilterLikelihood`)."""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

from pgm.core.frame import FrameContext

from .cf_features import MAX_DETECT_PX, Scan, response_peaks
from .likelihoods import grey_frame

__all__ = ["RedetectionScan"]


class RedetectionScan:
    """The re-detection scan of :class:`~pgm.observation.appearance.correlation.
    CorrelationFilterLikelihood` (a mixin: it reads that class's filters and settings)."""

    def _scan_cells(self) -> tuple[int, int, int, int]:
        """The rows ``r0:r1`` and columns ``c0:c1`` of the filter's cells over the
        object's box (a rectangle of ``box_cells``): the scan's kernel."""
        rows = np.flatnonzero(self.box_cells.any(axis=1))
        cols = np.flatnonzero(self.box_cells.any(axis=0))
        return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1

    def _scan_spectrum(self, fshape: tuple[int, int],
                       cells: tuple[int, int, int, int]) -> np.ndarray:
        """The spectrum (single precision, as the features'), at the scan's FFT size
        ``fshape``, of the long-term filter's cells over the object's box (``cells``,
        :meth:`_scan_cells`, cut out: a kernel of the box's size, not the window's, so the
        scan's FFT pads the frame by the box, not the window); kept while the filter is
        unchanged (it changes only on the frames it learns from, which a lost
        object's are not)."""
        cached = self._scan_filter
        if cached is not None and cached[0] is self.memory and cached[1] == fshape:
            return cached[2]
        num, den, _ = self.memory
        th, tw = self.hann.shape
        h = sfft.irfft2(np.conj(num) / self._regularised(den), s=(th, tw))
        # the filter's cells over the object's box only: its context (padding) learned the
        # background around the object, which stays where the object was
        r0, r1, c0, c1 = cells
        h = (np.fft.fftshift(h, axes=(-2, -1)) * self.box_cells)[:, r0:r1, c0:c1]
        hf = sfft.rfft2(h, s=fshape, axes=(-2, -1)).astype(np.complex64)
        self._scan_filter = (self.memory, fshape, hf)
        return hf

    def detect(self, ctx: FrameContext, centre, scale: float, max_peaks: int = 3) -> Scan:
        """Where the object may be in the whole frame: the highest peaks of the long-term
        filter's response over the frame at ``scale`` (relative to the first box), in
        units of its typical peak. Only the filter's cells over the object's box are
        used: the rest learned the background around the object, which stays where the
        object was.

        The frame is resampled to template pixels and correlated with the filters once
        (FFT); a frame wider than ``scan_side`` object sizes (``scan_side · target_px``
        template pixels, at most :data:`MAX_DETECT_PX`) is scanned in a window of that
        side around ``centre``. Returns a :class:`Scan`: the peaks'
        centres ``(m, 2)`` in image pixels, their relative responses ``(m,)`` and
        standard scores (in standard deviations of the map above its mean), highest
        first, at least a tenth of the object apart and with the whole box inside the
        frame (``m <= max_peaks``), and the number of independent values the map holds
        (its cells over the square of twice the target peak's width); cached per frame."""
        self.require_model()

        def make():
            grey = grey_frame(ctx)
            H, W = grey.shape
            step = self.ref_size * float(scale) / np.array(self.shape)  # image px / cell
            side = int(round(min(self.scan_side * self.target_px, MAX_DETECT_PX)))
            ow = min(int(np.ceil(W / step[0])), side)
            oh = min(int(np.ceil(H / step[1])), side)
            size = np.array([ow, oh]) * step
            c = np.asarray(centre, dtype=float)
            mid = np.array([W, H]) / 2.0 - 0.5
            # the scanned region: the frame, or a window around the estimate within it
            lo = np.clip(c - size / 2, -0.5, np.array([W, H]) - 0.5 - size)
            rc = np.where(size >= np.array([W, H]), mid, lo + size / 2)
            feats = self._window_features(ctx, rc, size, (ow, oh)).astype(np.float32)
            th, tw = self.hann.shape
            cells = self._scan_cells()
            r0, r1, c0, c1 = cells
            # linear (not circular) convolution with the box's kernel: padded by its size
            fshape = (sfft.next_fast_len(oh + r1 - r0 - 1, real=True),
                      sfft.next_fast_len(ow + c1 - c0 - 1, real=True))
            zf = sfft.rfft2(feats, s=fshape, axes=(-2, -1))
            best = sfft.irfft2(np.sum(self._scan_spectrum(fshape, cells) * zf, axis=0), s=fshape)
            # the kernel's centre cell (th // 2, tw // 2) is at (th // 2 - r0, tw // 2 - c0)
            best = best[th // 2 - r0:th // 2 - r0 + oh,
                        tw // 2 - c0:tw // 2 - c0 + ow].astype(float) / self.memory[2]
            # only where the whole box is in the frame: a box across the border reads
            # the border's replicated pixels
            half = self.ref_size * float(scale) / (1 + self.padding) / 2
            x0, y0 = rc - size / 2
            gx = x0 + (np.arange(ow) + 0.5) * step[0] - 0.5
            gy = y0 + (np.arange(oh) + 0.5) * step[1] - 0.5
            ok_x = (gx - half[0] >= -0.5) & (gx + half[0] <= W - 0.5)
            ok_y = (gy - half[1] >= -0.5) & (gy + half[1] <= H - 0.5)
            if not ok_x.any() or not ok_y.any():
                return Scan(np.zeros((0, 2)), np.zeros(0), np.zeros(0), 0.0)
            valid = ok_y[:, None] & ok_x[None, :]
            mean, sd = float(best[valid].mean()), float(best[valid].std()) + 1e-12
            best = np.where(valid, best, -np.inf)
            cells, vals = response_peaks(best, max(1, int(round(0.1 * self.target_px))),
                                         max_peaks)
            keep = np.isfinite(vals)
            xy = rc - size / 2 + (cells[keep] + 0.5) * step - 0.5
            # the map is correlated over about the target peak's width: one independent
            # value per (2 sigma)^2 cells
            corr = 2.0 * self.sigma * self.target_px
            return Scan(xy, vals[keep], (vals[keep] - mean) / sd,
                        float(valid.sum()) / max(corr * corr, 1.0))

        return self._cached(ctx, ("cf-detect", max_peaks), make)

    def open_windows_at(self, ctx: FrameContext, centres: np.ndarray) -> None:
        """Let this frame's particles near ``centres`` ``(m, 2)`` (image pixels) be read
        in windows of their own (``windows > 1``): where a proposal put them, at the
        peaks of :meth:`detect` it kept."""
        self._cached(ctx, ("cf-open",), list).append(np.asarray(centres, float).reshape(-1, 2))

    def opened(self, ctx: FrameContext) -> np.ndarray | None:
        """The centres ``(m, 2)`` this frame's windows may open at (:meth:`open_windows_at`;
        None: none)."""
        found = self._cached(ctx, ("cf-open",), list)
        return np.concatenate(found) if found else None
