"""Colour-histogram likelihood: quantisation, per-box histograms, Bhattacharyya.

The pieces, one module each: :mod:`~.quantize` (colour quantisation),
:mod:`~.cache` (the per-frame bin cache), :mod:`~.integral` (integral-histogram
kernels and the template-support coefficient), :mod:`~.grid` (kernel-weighted grid
histograms) and :mod:`~.scorer` (:class:`ColourHistogramScorer`).

This is the hot path of every colour tracker (the colour likelihood of Pérez et al.
[#perez2002]): score N candidate boxes of one frame against a template histogram ``q``. It
is one vectorised computation, with no Python loop over boxes:

1. **Quantise only what is scored, once per frame** (:func:`quantize_colour`): one
   ``cv2.cvtColor`` to 8-bit HSV, then per-channel bit shifts (power-of-two bin
   counts), one ``cv2.convertScaleAbs`` (hue) or lookup tables, combined with
   saturating ``cv2`` adds and a ``cv2.min``; a region whose three channels are equal
   (greyscale video delivered as BGR) skips ``cvtColor``: its hue and saturation are
   0 and its value is the grey level. :class:`ColourHistogramScorer` quantises
   *lazily*: only the union rectangle of the boxes it scores (clipped to the image,
   plus a ``_ROI_MARGIN`` of 4 px), into a full-size bin buffer cached in the
   :class:`~pgm.core.frame.FrameContext` under ``("colour-bins", layout, n_h, n_s, n_v)``
   (a ``_FrameBins``: the buffer plus the rectangle quantised so far). Every factor
   that shares a layout shares it: a request inside the rectangle costs nothing,
   otherwise only the strips that grow it to the bounding rectangle are quantised,
   and the first request of a frame also covers the previous frame's requests (so
   the three band factors of one face cost one quantisation call per frame).
   :meth:`ColourHistogramScorer.bins` still returns the whole frame (quantising what
   is left). Measured on FaceOcc1 (352x288, greyscale) / PETS (768x576): the full
   frame costs 0.3 / 1.3 ms, the union of 30 boxes around the face / a person about
   0.08 / 0.1-0.2 ms.
2. **Integral histograms over the union rectangle only** (:func:`box_histograms`):
   the boxes are rounded to integer pixel bounds and clipped to the image; the
   union bounding rectangle of the clipped boxes is cropped, turned into a uint8
   one-hot cube laid out *bin-major in groups of four bins* (``(G, h, w, 4)``), and
   integrated by one ``cv2.integral`` call per block of groups (the groups are
   stacked vertically: a rectangle sum inside one group never reads another
   group's rows, so stacking is exact). The four corners of every box are then
   gathered with one ``np.take`` per block: ``4 N`` rows of four int32 per group.
   Blocks are sized so that a block's integral (about 2 MiB) stays in cache between
   ``cv2.integral`` and the gather (this matters for 256-bin layouts), and the
   temporaries live in per-thread scratch buffers reused between calls (fresh
   multi-MB allocations cost page faults on every call: 4.5 instead of 1.5 µs per box).
   With few boxes the integral is taken on the *compressed grid* of the boxes'
   distinct corner coordinates instead (cells between consecutive distinct ``x``
   and ``y`` corners, found by marks and a running sum, no sort): one 3-D
   ``cv2.calcHist`` of (bin slot, cell row, cell column) uint8 images counts every
   (bin, cell), then one ``cv2.integral`` over far fewer cells than pixels and one
   gather of the corners. About 60 numpy/cv2 calls per ``rho`` in all whatever N: at
   tracker sizes (N = 10-100) numpy's per-call overhead, not pixels, dominates.
   ``"auto"`` picks dense or compressed by a cost model fitted to measurements
   (:func:`_counts`): compressed for the 10-100 boxes of a tracker around one
   object, dense for hundreds of spread boxes. Both are exact (bit-identical counts).
3. **Only the template's bins** (:meth:`ColourHistogramScorer.rho`): the
   Bhattacharyya coefficient ``sum_u sqrt(p_u q_u)`` needs ``p_u`` only where
   ``q_u > 0``, and the normaliser of ``p`` is the box's in-image pixel count, known
   without counting. So the integral cube is built for the template's support only
   (typically 30-90 of 256 HSV bins, at most 16 of 80 "perez" bins on a greyscale
   frame). This is exact, not an approximation.

Measured alternatives (integral cube for the union, 162x196 px, of 1000 boxes 40x80
with centres N(point, 20 px) on a 768x576 PETS frame, one thread, ms; all 256 HSV
bins / the template's 86): ``np.cumsum`` over an int32 one-hot cube 63 / 22, over a
uint16 cube 46 / 16 (numpy's accumulate is not vectorised along either axis);
``np.add`` row-then-column loops in uint16 7.3 / 3.0; ``cv2.integral`` pixel-major
with B channels 32 / 3.3 (at most 128 channels per call); ``cv2.integral`` on
single-bin planes 3.4 / 1.0; on bin-major groups of four (used) 2.7 / 0.8. Gathers
from bin-major groups of four beat single-bin planes 2x; an unblocked 256-bin cube
is 2.5x slower at N = 1000 (cache misses in the gather). See
``benchmarks/likelihood.py --alternatives``.

Box rounding: a box ``(cx, cy, w, h)`` covers pixel columns
``[x0, x1) = [floor(cx - w/2 + 1/2), floor(cx + w/2 + 1/2))`` (round half up), with
``x1 = max(x1, x0 + 1)`` so that a valid box always covers at least one pixel
column; rows likewise. The in-image fraction ``in_frac`` is the number of those
pixels inside the image over their total number; the histogram is normalised over
the in-image pixels only (this toolkit's convention: pixels outside the image are absent).

References
----------
.. [#perez2002] P. Pérez, C. Hue, J. Vermaak and M. Gangnet, "Color-based probabilistic
   tracking", Proc. ECCV 2002, LNCS 2350, 661–675. doi:10.1007/3-540-47969-4_44
"""

from pgm.observation.appearance.colour.integral import box_histograms, pixel_bounds
from pgm.observation.appearance.colour.quantize import LAYOUTS, colour_bin_count, quantize_colour
from pgm.observation.appearance.colour.scorer import KERNELS, ColourHistogramScorer, bhattacharyya

__all__ = ["quantize_colour", "colour_bin_count", "box_histograms", "bhattacharyya",
           "pixel_bounds", "ColourHistogramScorer", "LAYOUTS", "KERNELS"]
