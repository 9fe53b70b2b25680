"""Bhattacharyya similarity and :class:`ColourHistogramScorer`, the colour factors' engine.

References
----------
.. [#perez2002] P. Pérez, C. Hue, J. Vermaak and M. Gangnet, "Color-based probabilistic
   tracking", Proc. ECCV 2002, LNCS 2350, 661–675. doi:10.1007/3-540-47969-4_44
.. [#nummiaro2003] K. Nummiaro, E. Koller-Meier and L. Van Gool, "An adaptive color-based
   particle filter", Image and Vision Computing 21(1), 99–110, 2003.
   doi:10.1016/S0262-8856(02)00129-4
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

from pgm.core.errors import InputError
from pgm.core.frame import FrameContext
from pgm.observation.appearance.colour.cache import _FrameBins
from pgm.observation.appearance.colour.gather import _gathered_histograms
from pgm.observation.appearance.colour.grid import _grid_histograms
from pgm.observation.appearance.colour.integral import (
    _ROI_MARGIN,
    _bounds,
    _check_boxes,
    _counts,
    _histograms,
    _rho_of_template,
    _Template,
    _union_of,
)
from pgm.observation.appearance.colour.quantize import (
    _as_bgr,
    _bin_count,
    _check_count,
    _resolve_layout,
)

__all__ = ['bhattacharyya', 'ColourHistogramScorer', 'KERNELS']

KERNELS = ("uniform", "epanechnikov", "grid-uniform")
#: prepared templates a scorer keeps (least recently used dropped first): one per learner
#: that scores through it in a frame — a plate of many replicas shares one scorer — so
#: this bounds memory (an entry is a few kB), not the replicas a frame may have
TEMPLATE_CACHE = 1024


def bhattacharyya(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Bhattacharyya coefficient ``sum_u sqrt(p_u q_u)`` of each row of ``p``.

    ``p`` is ``(N, B)`` (or ``(B,)``, giving a scalar array), ``q`` is ``(B,)``; both
    are expected to be normalised, non-negative histograms.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    if q.ndim != 1 or p.shape[-1:] != q.shape or p.ndim > 2:
        raise InputError(f"bhattacharyya: p must be (N, B) and q (B,), got {p.shape} "
                         f"and {q.shape}")
    if np.any(p < 0) or np.any(q < 0) or not (np.all(np.isfinite(p))
                                              and np.all(np.isfinite(q))):
        raise InputError("bhattacharyya: histograms must be finite and non-negative")
    return np.sqrt(p) @ np.sqrt(q)


class ColourHistogramScorer:
    """Colour-histogram likelihood of candidate boxes (Pérez et al. [#perez2002]).

    ``rho(ctx, boxes)`` is the Bhattacharyya coefficient between each box's
    histogram and the template ``q``, multiplied by the box's in-image fraction, so
    that a box mostly off the image cannot win on a sliver and a box wholly outside
    scores 0. The log-likelihood is then ``-lam * (1 - rho)``.

    Parameters
    ----------
    layout, n_h, n_s, n_v, n_rgb
        Bin layout; see :func:`quantize_colour`.
    kernel : {"uniform", "epanechnikov", "grid-uniform"}
        ``"uniform"`` (default): every pixel of the box counts once; exact, by
        integral histograms. ``"epanechnikov"``: the kernel of Nummiaro et al.
        [#nummiaro2003], ``k(r) = 1 - r^2``, ``r`` the normalised elliptical radius in
        the box; integral histograms cannot weight pixels, so this is a *grid approximation*:
        a fixed ``grid x grid`` lattice of sample points in every box (the points
        with ``r < 1``), each reading the pixel that contains it. ``"grid-uniform"``:
        the same lattice with unit weights (an approximation of "uniform").
    grid : int
        Lattice size of the grid kernels (default 16: 256 samples, 200 inside the
        Epanechnikov ellipse).
    q : array (B,), optional
        Template histogram; normally set by :meth:`template`.
    """

    def __init__(self, layout: str = "perez", n_h: int = 16, n_s: int = 4,
                 n_v: int | None = None, kernel: str = "uniform", *, grid: int = 16,
                 n_rgb: int = 8, q: np.ndarray | None = None):
        self._canon = _resolve_layout(layout, n_h, n_s, n_v, n_rgb)
        if kernel not in KERNELS:
            raise InputError(f"unknown kernel {kernel!r}; expected one of {KERNELS}")
        self.kernel = kernel
        self.grid = _check_count("grid", grid, 4096)
        self.q: np.ndarray | None = None if q is None else self._check_q(q)
        self._templates: OrderedDict[tuple, Any] = OrderedDict()  # least recently used first
        self._requested: list[int] | None = None   # see _FrameBins (hint)

    # parameters ----------------------------------------------------------------------
    @property
    def layout(self) -> str:
        return self._canon[0]

    @property
    def n_bins(self) -> int:
        return _bin_count(self._canon)

    @property
    def cache_key(self) -> tuple:
        """``FrameContext`` cache key of the frame's lazily quantised bins (a
        ``_FrameBins``: full-size buffer plus the rectangle quantised so far, shared
        by every scorer of the same layout)."""
        return ("colour-bins",) + self._canon

    def __repr__(self) -> str:
        lay, a, b, c = self._canon
        return (f"ColourHistogramScorer(layout={lay!r}, bins=({a}, {b}, {c}), "
                f"kernel={self.kernel!r})")

    # frames --------------------------------------------------------------------------
    @staticmethod
    def _ctx(image_or_ctx: Any) -> FrameContext:
        if isinstance(image_or_ctx, FrameContext):
            return image_or_ctx
        return FrameContext(0, image_or_ctx)

    def _frame(self, image_or_ctx: Any) -> _FrameBins:
        """The frame's lazily quantised bins (cached in the context)."""
        ctx = self._ctx(image_or_ctx)
        if ctx.image is None:
            raise InputError(f"frame {ctx.index} has no image")
        frame = ctx.cached(self.cache_key,
                           lambda: _FrameBins(ctx.image, self._canon, self._requested))
        self._requested = frame.requested        # this frame's requests: next one's hint
        return frame

    def bins(self, image_or_ctx: Any) -> np.ndarray:
        """The frame's whole bin image, quantised once per frame (cached in the
        context; regions already quantised for boxes are not quantised again)."""
        return self._frame(image_or_ctx).full()

    def _check_q(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n_bins,):
            raise InputError(f"template must have shape ({self.n_bins},), got {q.shape}")
        if not np.all(np.isfinite(q)) or np.any(q < 0) or q.sum() <= 0:
            raise InputError("template must be finite, non-negative and not all zero")
        return q / q.sum()

    def _template_of(self, q: Any) -> _Template:
        """Prepared template of ``q`` (validated and normalised) or, for None, of the
        stored ``self.q`` (used as it is); cached by value, so a caller passing the same
        array every frame pays neither the checks nor the preparation again."""
        if q is None:
            if self.q is None:
                raise InputError("no template: call template() first or pass q")
            arr, raw = np.asarray(self.q), True
        else:
            arr, raw = np.asarray(q, dtype=float), False
        key = (raw, arr.dtype.str, arr.shape, arr.tobytes())
        t = self._cached_template(key)
        if t is None:
            t = self._keep_template(key, _Template(np.array(arr) if raw else
                                                   self._check_q(arr), self.n_bins))
        return t

    def _cached_template(self, key: tuple) -> Any:
        """A prepared template (or set of them) if it is cached, marked as just used."""
        t = self._templates.get(key)
        if t is not None:
            self._templates.move_to_end(key)
        return t

    def _keep_template(self, key: tuple, prepared: Any) -> Any:
        """Cache ``prepared``, dropping the least recently used beyond
        :data:`TEMPLATE_CACHE` (one scorer serves every learner of a factor — each replica
        of a plate scores against its own template — so the cache holds one entry per
        learner, not per factor)."""
        self._templates[key] = prepared
        while len(self._templates) > TEMPLATE_CACHE:
            self._templates.popitem(last=False)
        return prepared

    # scoring -------------------------------------------------------------------------
    def histograms(self, image_or_ctx: Any,
                   boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(hist (N, B), in_frac (N,))`` of the boxes under this scorer's kernel."""
        frame = self._frame(image_or_ctx)
        b = _check_boxes(boxes)
        if self.kernel == "uniform":
            return _histograms(frame.bins, self.n_bins, b, frame)
        return _grid_histograms(frame.bins, self.n_bins, b, self.kernel, self.grid, frame)

    def box_histograms(self, image_or_ctx: Any, boxes: np.ndarray,
                       levels: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`histograms` (the uniform kernel) of a few boxes from their own pixels
        only: nothing else of the frame is quantised (detections over a large frame;
        :meth:`histograms` quantises the boxes' union, cheaper for many overlapping
        boxes). Box ``i`` is read on the lattice of every ``2**levels[i]``-th pixel of
        every ``2**levels[i]``-th row (``levels`` None: every pixel, equal to
        :meth:`histograms` with ``kernel="uniform"``)."""
        ctx = self._ctx(image_or_ctx)
        if ctx.image is None:
            raise InputError(f"frame {ctx.index} has no image")
        return _gathered_histograms(_as_bgr(ctx.image), self._canon, self.n_bins,
                                    _check_boxes(boxes), levels)

    def template(self, image_or_ctx: Any, box: np.ndarray) -> np.ndarray:
        """Histogram ``(B,)`` of one box ``(cx, cy, w, h)``; also stored as ``self.q``."""
        b = np.asarray(box, dtype=float)
        if b.shape == (4,):
            b = b[None, :]
        if b.shape != (1, 4):
            raise InputError(f"template box must have shape (4,), got {b.shape}")
        hist, in_frac = self.histograms(image_or_ctx, b)
        if in_frac[0] <= 0:
            raise InputError(f"template box {b[0].tolist()} lies wholly outside the image")
        self.q = hist[0] / hist[0].sum()
        return self.q.copy()

    def rho(self, image_or_ctx: Any, boxes: np.ndarray,
            q: np.ndarray | None = None) -> np.ndarray:
        """Bhattacharyya coefficient x in-image fraction, ``(N,)``, of each box.

        ``q`` defaults to the stored template (:meth:`template`). Only the boxes'
        union rectangle of the frame is quantised (once per frame and layout).
        """
        t = self._template_of(q)
        b = _check_boxes(boxes)
        frame = self._frame(image_or_ctx)
        if self.kernel == "uniform":
            return _rho_of_template(frame.bins, b, t, frame)
        hist, in_frac = _grid_histograms(frame.bins, self.n_bins, b, self.kernel,
                                         self.grid, frame)
        return (np.sqrt(hist) @ t.sqrt_q) * in_frac

    def rho_many(self, image_or_ctx: Any, boxes: np.ndarray, templates: np.ndarray,
                 owner: np.ndarray) -> np.ndarray:
        """:meth:`rho` of boxes scored against *several* templates in one pass.

        ``templates`` ``(K, B)``; box ``i`` is scored against ``templates[owner[i]]``.
        One integral-histogram pass over the union of the boxes counts the union of
        the templates' supports, so the factors of a part graph (one template per part,
        one frame) cost one call instead of one each. Equal to :meth:`rho` per box.
        """
        if self.kernel != "uniform":
            return np.concatenate([self.rho(image_or_ctx, boxes[owner == k], templates[k])
                                   for k in range(len(templates))])[np.argsort(
                                       np.argsort(owner, kind="stable"), kind="stable")]
        T = np.asarray(templates, dtype=float)
        key = ("many", T.shape, T.tobytes())
        prepared = self._cached_template(key)
        if prepared is None:
            qs = np.array([self._check_q(q) for q in T])
            t = _Template((qs > 0).any(axis=0).astype(float), self.n_bins)
            support = np.flatnonzero(t.slot_of_bin < t.k)
            prepared = self._keep_template(key, (t, np.sqrt(qs[:, support])))
        t, sqrt_q = prepared
        b = _check_boxes(boxes)
        frame = self._frame(image_or_ctx)
        bins = frame.bins
        ints, inside, in_frac = _bounds(b, *bins.shape)
        union, all_nonempty = _union_of(ints, inside)
        if union is not None:
            frame.ensure(*union, margin=_ROI_MARGIN)
        counts = _counts(bins, ints, union, all_nonempty, t.slot_of_bin, t.k, slot8=t.slot8)
        root = np.sqrt(counts.astype(np.float64, copy=False))
        num = np.einsum("ij,ji->i", sqrt_q[np.asarray(owner)], root)  # counts are (k, N)
        return num / np.sqrt(np.maximum(inside, 1)) * in_frac

    def log_likelihood(self, image_or_ctx: Any, boxes: np.ndarray, lam: float = 20.0,
                       q: np.ndarray | None = None) -> np.ndarray:
        """``-lam * (1 - rho)`` (default ``lam = 20``, as in [#perez2002])."""
        return -float(lam) * (1.0 - self.rho(image_or_ctx, boxes, q))


