"""The default multi-target model: OC-SORT's association, its filtered boxes, a colour model
per track, thresholds on the video's own score quantiles, gated by what the video shows
of its clutter, a life cycle that asks a track
found again for the evidence a new one needs, and short gaps filled.

:mod:`pgm.models.ocsort`'s graph with eleven of the ideas this toolkit adds to the classic
cores, each one setting:

* ``report="estimate"`` — a matched track reports its Kalman posterior box (the filtered
  box, which averages the detector's jitter) instead of the raw detection;
* ``appearance="colour"`` — each track keeps a colour histogram (the toolkit's
  :class:`~pgm.observation.appearance.likelihoods.ColourHistogramLikelihood`) learned
  from the detections it is given, and the association adds its similarity to each
  detection (``exp(ρ − 1)``, weight 1) to the IoU and OC-SORT's momentum term, so that
  people who cross keep their identities (each detection's histogram read once per frame
  from between 1 024 and 4 096 of its pixels, :mod:`pgm.core.resolution`);
* ``score_map="placed-over"``, ``score_threshold=0.2`` — a detection's score is read
  as 0 where the video shows the detections at that score to be more likely clutter
  than of a target, by how seldom they are found again in the next frame above the
  scene's chance level, and above that clutter as its quantile among the video's scores
  above it (:class:`~pgm.factors.persistent_quantiles.PersistentQuantiles`): that
  clutter, and the lowest fifth of the rest, are neither used nor start tracks —
  unless the tracker's own tracks show that fifth, as a group, on their people (IoU 0.5
  with a tracked person's predicted box) at least 0.8 times as often as the
  best-scored detections are, and then it is used as the rest. That is a statement
  about the detections, so any strictly increasing map of the scores (a probability, a
  logit, a margin) gives the same tracks; a detector run at a lower threshold, whose
  added clutter lies below its usual output, has the same fifth of that output cut as
  before (the gated quantile, ``"placed"``, read the clutter as the fifth and let the
  lowest of the usual output through); and one run at a higher threshold, whose lowest
  fifth is people, keeps them (on the shared detectors the lowest fifth is mostly boxes
  beside a person — a part, a box too large, one off by half a width — and stays cut:
  ``python benchmarks/detection_errors.py``). With ``"placed-over"`` that evidence
  also outranks the clutter reading for the boxes it is about: a box read as clutter
  that lies on a tracked person's predicted box (IoU 0.5), at a score whose boxes are
  on their people as often as the best-scored ones, is used too (in a crowd the
  found-again rate reads a partly hidden person's low scores as clutter);
* ``rounds=rounds()`` — OC-SORT's two rounds take the detections above the threshold;
  a third, the **presence round**, gives a detection below it (but not read as clutter)
  to a track matched in the previous frame that it overlaps by at least 0.5, and the
  match keeps the track without updating it (``"update": false``: its state, last box,
  motion history and colour model stay as predicted). On the shared detectors the
  lowest fifth of the scores is 30 to 40 % on a person (IoU 0.5 with the
  truth, ``python benchmarks/detection_errors.py``): such a box says that the person is
  there, not where, and drawn into the filter it pulls tracks off their people
  (TUD-Campus, MOTA / IDF1: 0.638 / 0.705 without the round, 0.524 / 0.498 when it
  updates every track, 0.579 / 0.686 as it is: a track kept on its prediction is
  sometimes off its person). A
  detector run at a higher threshold has no clutter in its lowest fifth, and there the
  round keeps the tracks the threshold would lose (the synthetic scene with its lowest
  40 % of scores removed: MOTA 0.441 without the round, 0.754 with it);
* ``consecutive=False`` — confirmation counts matches rather than matches in a row
  (SORT's count);
* ``recover_hits=3`` — a track found again after a miss is reported once it has been
  matched three frames in a row (at 30 frames/s; the evidence a new track needs), so a
  single false detection near a lost track does not bring it back; the frames it waited
  are then filled with the rest of its gap (``fill_gaps`` below);
* ``birth_iou=0.3`` — no track is born on a detection that overlaps a track's predicted
  box (or another birth of the frame) by more than the association's own IoU gate: a
  detection the association could have given to a track is explained by it, so a
  detector's second box on a person or a box on part of one starts no second identity
  (on MOT16-11's DPM detections 24 % of the boxes overlap a higher-scored one by more
  than 0.2, and 90 % of those are on no person; the package's cores, ``birth_iou=1``,
  start a track on each);
* ``explain_tentative="prediction"`` — the same rule on every match of a track not yet
  confirmed (a birth in progress): it is removed when its detection overlaps a confirmed
  track's predicted box by more than 0.3, so a box born beside a person that drifts onto
  them never becomes a second identity;
* ``fill_gaps=0.5`` — a track reported again after at most half a second also reports
  the frames between, once it has been matched as many frames in a row as a new track
  needs, its box interpolated between the two it reported in the world the camera sees
  (through the camera's motion over the gap), written to the track file when it is
  found (the annotated video shows what was known at each frame); a gap two tracks
  bound together (overlapping at both its ends: a second box on one person) is left
  empty;
* ``fill_births=True`` — a track confirmed also reports the frames it was tentative in,
  with the boxes it had then, written when it is confirmed: the confirmation count is
  evidence asked before a track is reported, not frames lost.
* ``noise_per="detection"`` — the Kalman process noise, read as at 30 frames/s, is the
  same step at each detection at any frame rate (its rates put in the video's units)
  rather than a random walk that grows with the time between frames: what it models is
  the boxes' irregularity from one detection to the next (a person's box changes with
  the pose; a walker's velocity varies about its mean, it does not drift), so at 7 or
  10 frames/s the filter does not chase the detections' jitter.

Chosen **leave one sequence out** over the five shared MOT sequences and the toolkit's
synthetic crossing scene, each as it is and under 13 kinds of perturbation (score maps,
frame rate, dropped, jittered, extra and shifted detections, the detector run at a lower
and at a higher threshold), among the candidates of every core (``python
benchmarks/robustness.py``; numbers in ``docs/results.md``): the best mean over all six,
0.6507 of (MOTA + IDF1 + HOTA) / 3 over the 84 cells, against 0.6505 for
``"placed-rebased"`` (the default before, itself the best of the 53 candidates before
it) and 0.6443 for ``"placed"``; every fold picks it by that mean (by the worst margin
to the peers the TUD-Stadtmitte fold ties). Held out, it is below the best of
the six peers in one cell of 84 (TUD-Stadtmitte with the detector at a higher
threshold: IDF1 −0.020, HOTA −0.014). It needs the
frames (for the colour models) and, where the camera moves, compensates its motion as
``pgm track`` does by default. ``pgm track`` runs it on a folder with detections when no
``--model`` is given.

>>> g = build_graph(Params())
>>> [type(a).__name__ for a in g.factors["association"].appearance]
['ColourHistogramLikelihood']
>>> g.plates[0].lifecycle.report, g.plates[0].lifecycle.recover_hits
('matched', 3)
>>> g.plates[0].lifecycle.birth_iou, g.plates[0].lifecycle.explain_tentative
(0.3, 'prediction')
>>> g.plates[0].lifecycle.fill_gaps, g.plates[0].lifecycle.fill_births  # 0.5 s at 30/s
(15, True)
>>> build_graph(Params(fps=7.0)).plates[0].lifecycle.confirm_hits
1
>>> g.factors["association"].score_map, [r["min_score"] for r in g.factors["association"].rounds]
('placed-over', [0.2, 0.2, 1e-09])
>>> [(r["max_score"], r["tracks"], r["update"]) for r in g.factors["association"].rounds][2]
(0.2, 'tracked', False)
>>> import numpy as np  # at a third of 30 frames/s: the rates' variance times 9, not 27
>>> slow = np.diag(build_graph(Params(fps=10.0)).factors["transition:box"].Q)
>>> np.round(slow / np.diag(g.factors["transition:box"].Q), 6).tolist()
[1.0, 1.0, 1.0, 1.0, 9.0, 9.0, 9.0]
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

from pgm.core.graph import FactorGraph

from . import config as _config
from . import ocsort, sort

__all__ = ["ABOVE_GATE", "CONFIG", "Params", "build_graph", "rounds"]


#: the least mapped score of a detection the presence round takes: above the gated
#: quantile's 0 (a detection the video shows more likely clutter), below any quantile a
#: detection kept has (above ``u*``)
ABOVE_GATE = 1e-9


def rounds(threshold: float = 0.6) -> tuple[dict, ...]:
    """OC-SORT's two rounds on the detections scoring at least ``threshold`` (OC-SORT's
    0.6; ``Params.score_threshold`` moves it), then the presence round: a detection below
    it (and above the gate) keeps a track matched in the previous frame that it overlaps
    by at least 0.5 (BoT-SORT's second round), without updating it."""
    return ocsort.rounds(threshold) + ({"iou": 0.5, "min_score": ABOVE_GATE,
                                         "max_score": threshold, "tracks": "tracked",
                                         "update": False},)


@dataclass(frozen=True)
class Params(ocsort.Params):
    """:class:`pgm.models.ocsort.Params` reporting the filtered boxes, with colour
    appearance in the association, score quantiles above the clutter the detections found
    again show (the lowest fifth cut unless the tracks show it on its people), the detections
    below the threshold keeping a track without updating it (the presence
    round of :func:`rounds`), SORT's confirmation count, its per-frame
    constants read at 30 frames/s, a track found again reported after three matches in
    a row, no birth, nor tentative track, on a detection a track explains, gaps of up to
    0.5 s filled, a track's tentative frames reported when it is confirmed, and the Kalman
    noise a step per detection at any frame rate."""

    report: str = "estimate"
    appearance: str | None = "colour"
    appearance_weight: float = 1.0
    score_map: str = "placed-over"
    score_threshold: float | None = 0.2
    rounds: tuple[dict, ...] = field(default_factory=rounds)
    recover_hits: int = 3
    consecutive: bool = False
    reference_fps: float | None = 30.0
    birth_iou: float = 0.3
    explain_tentative: str = "prediction"
    fill_gaps: float = 0.5
    fill_births: bool = True
    noise_per: str = "detection"


def build_graph(params: Params | None = None, name: str = "ocsort-colour") -> FactorGraph:
    """OC-SORT's graph with the filtered boxes and colour appearance."""
    return sort.build_graph(params or Params(), name=name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "ocsort-colour", "multi-target", sys.modules[__name__],
    "the multi-target default: OC-SORT's association reporting its filtered boxes, a colour "
    "model per track, thresholds on score quantiles, a low-scored box keeping a track without "
    "moving it, constants per second, short gaps filled "
    "(chosen leave one sequence out over sequences and perturbations)",
    options=sort.OPTIONS, build=sort.video_build)
