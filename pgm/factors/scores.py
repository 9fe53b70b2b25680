r"""Detection scores in the PHD measurement model, calibrated on the video itself.

A public detection is a box *and a score*, in the detector's own units (MOT15's ACF
scores run from about 0 to 140, MOT16's DPM margins from about −0.5 to 4). Treating the
score as a *mark* of the measurement, a detection ``(z, s)`` comes from a target with
density ``p_D g(z|x) f_T(s)`` and from clutter with ``κ f_C(s)`` (``f_T, f_C``: the score
densities of true and false detections). Dividing the PHD corrector's
``L(z) = κ f_C(s) + ν_b f_T(s) + Σ_j p_D g(z|x_j) f_T(s) w_j`` by ``f_T(s)`` leaves the
score-blind corrector with a **per-detection clutter intensity**

.. math::  κ(s) = κ\, \big[f_C(s) / f_T(s)\big]^{γ}

(``γ`` a temper, 1 the literal model): a high-score detection is hard to explain as
clutter, so it earns more birth mass and a larger share of the intensity; a low-score
one is readily written off as clutter unless a target predicts it. Equivalently
``p_D(s) / κ(s)`` carries the score's likelihood ratio.

``f_T`` and ``f_C`` are never taken from ground truth: :class:`ScoreMixture` fits a
two-component Gaussian mixture to the scores seen so far (EM, online, warm-started each
frame), the component with the higher mean being the targets. EM is affine-equivariant,
so the fitted ratio does not depend on the detector's units — the same settings serve
MOT15's and MOT16's detectors. (A rank transform would make it invariant to any
monotone re-scaling, but a Gaussianised rank marginal is exactly normal and the
mixture is then not identifiable; the shape of the raw score distribution is the
information.) The ratio is evaluated with the score clipped to the span between the two
component means (so it is monotone and saturates in the tails, where two Gaussians'
ratio is an artefact) and clipped to ``[1/max_ratio, max_ratio]``.

**Low-score detections extend, never start, tracks** (as ByteTrack does): a detection
whose posterior probability of being a target, ``π f_T / (π f_T + (1−π) f_C)``, is below
``birth_min_prob`` gets no newborn particles; it still enters the corrector, so it
keeps a predicted target alive.

Where a tracked target's detections score like any detection rather than like the
target class (``persisting="all"``), the corrector is divided by the marginal score density
instead; see :class:`ScoreSettings`.

The clutter *rate* may also be calibrated from the fit: ``λ_c = (1 − π) ×`` the mean number
of detections per frame (``clutter_from_scores``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import iou_xywh, xywh_to_cxcywh
from pgm.core.numerics import check_finite_param
from pgm.factors.persistence import PersistenceScoreModel  # noqa: F401 (exported)
from pgm.factors.sorted_scores import SortedScores

__all__ = ["ScoreSettings", "ScoreMixture", "ScoreCalibration", "SCORE_MODELS", "PERSISTING",
           "shadowed", "PersistenceScoreModel", "ScoreQuantiles", "mid_ranks",
           "SCORE_MAPS", "LEARNED_SCORE_MAPS", "map_scores"]

SCORE_MODELS = ("off", "mixture", "learned")
PERSISTING = ("target", "all")


@dataclass(frozen=True)
class ScoreSettings:
    """How a PHD measurement factor uses detection scores.

    Attributes
    ----------
    model : str
        ``"off"``: scores ignored (the score-blind filter); ``"mixture"``: the
        per-detection clutter intensity ``κ(s)`` from a two-class mixture fitted online
        to the video's own scores (:class:`ScoreMixture`; the same for any affine map of
        the scores); ``"learned"``: the ratio from the probability that a detection is of
        a target, learned on the video from which detections are found again and read
        from the score's rank (:class:`PersistenceScoreModel`; the same for any strictly
        increasing map of the scores): ``f_T/f_C = [p/(1−p)] / [π/(1−π)]`` with ``π``
        the mean probability over the video's detections so far.
    temper : float
        ``γ ≥ 0``: exponent of the score likelihood ratio (0: scores ignored in the
        corrector; the birth gate still applies).
    max_ratio : float
        The likelihood ratio is clipped to ``[1/max_ratio, max_ratio]`` (≥ 1).
    birth_min_prob : float
        Detections whose posterior probability of being a target is below this get no
        births (they may only update existing targets); 0 turns the gate off.
    min_samples : int
        Scores to collect before the first fit; until then the filter is score-blind.
    clutter_from_scores : bool
        Replace the clutter rate ``λ_c`` by ``(1 − π) ×`` the mean detections per frame
        of the fit (``π``: the target class's share).
    em_iter : int
        EM iterations per frame (warm-started from the previous frame's fit; the first
        fit runs ``10 ×`` as many).
    persisting : str
        The score density of a *persisting* target's detection: ``"target"`` (the
        target class's ``f_T``, the literal marked model: ``κ(s) = κ (f_C/f_T)^γ``) or
        ``"all"`` (the marginal ``f = π f_T + (1 − π) f_C`` of every detection: a tracked
        person, partly occluded, scores like any detection, so ``κ(s) = κ (f_C/f)^γ`` —
        at most ``(1 − π)^{−γ}`` times ``κ`` — and only *births* carry the target class's
        ratio, ``ν_b(s) = ν_b (f_T/f)^γ``).
    shadow_iou : float
        A detection that overlaps a *higher-scored* detection of the same frame by at
        least this IoU starts no births (it may still update a target); 0 turns the
        rule off. Detectors suppress overlapping boxes (non-maximum suppression) up to
        their own threshold, and what survives just below it is mostly the same person
        found again at another position or scale (see :func:`shadowed`). Works with
        ``model="off"`` too.
    """

    model: str = "off"
    temper: float = 1.0
    max_ratio: float = 100.0
    birth_min_prob: float = 0.5
    min_samples: int = 50
    clutter_from_scores: bool = False
    em_iter: int = 5
    persisting: str = "target"
    shadow_iou: float = 0.0

    def __post_init__(self) -> None:
        if self.model not in SCORE_MODELS:
            raise ValueError(f"scores.model must be one of {SCORE_MODELS}, got {self.model!r}")
        check_finite_param("scores.temper", self.temper, nonneg=True)
        check_finite_param("scores.max_ratio", self.max_ratio, positive=True)
        if self.max_ratio < 1.0:
            raise ValueError(f"parameter 'scores.max_ratio' must be >= 1, got {self.max_ratio}")
        check_finite_param("scores.birth_min_prob", self.birth_min_prob, nonneg=True)
        if self.birth_min_prob > 1.0:
            raise ValueError("parameter 'scores.birth_min_prob' must be in [0, 1], got "
                             f"{self.birth_min_prob}")
        for name, lo in (("min_samples", 2), ("em_iter", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ValueError(f"scores.{name} must be an integer >= {lo}, got {v!r}")
        check_finite_param("scores.shadow_iou", self.shadow_iou, nonneg=True)
        if self.shadow_iou > 1.0:
            raise ValueError("parameter 'scores.shadow_iou' must be in [0, 1], got "
                             f"{self.shadow_iou}")
        if self.persisting not in PERSISTING:
            raise ValueError(f"scores.persisting must be one of {PERSISTING}, got "
                             f"{self.persisting!r}")
        if not isinstance(self.clutter_from_scores, (bool, np.bool_)):
            raise ValueError("scores.clutter_from_scores must be a bool, got "
                             f"{self.clutter_from_scores!r}")

    @property
    def enabled(self) -> bool:
        """Whether the factor reads scores at all (the mixture, or the shadow rule)."""
        return self.model != "off" or self.shadow_iou > 0

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def coerce(cls, value: ScoreSettings | dict[str, Any] | str | None,
               what: str) -> ScoreSettings:
        """``value`` as settings: an instance, a dict (from a saved graph, checked key by
        key), a model name, or None (the defaults)."""
        if value is None:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            return cls(model=value)
        if not isinstance(value, dict):
            raise ValueError(f"{what} must be ScoreSettings, a dict or a model name, "
                             f"got {value!r}")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(value) - names)
        if unknown:
            raise ValueError(f"{what}: unknown setting(s) {unknown} (known: {sorted(names)})")
        return cls(**value)


@dataclass
class ScoreMixture:
    """A two-component 1-D Gaussian mixture over detection scores; component 1 (the
    higher mean) is the target class. Fitted by EM, vectorised over the scores."""

    weight: float = 0.5  # π: share of the target class
    mean: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))
    var: np.ndarray = dataclasses.field(default_factory=lambda: np.ones(2))

    @classmethod
    def initial(cls, scores: np.ndarray) -> ScoreMixture:
        """A start from the 25 % / 75 % quantiles (deterministic)."""
        s = np.asarray(scores, dtype=float)
        lo, hi = np.quantile(s, [0.25, 0.75])
        v = max(float(np.var(s)) / 4.0, _var_floor(s))
        return cls(0.5, np.array([lo, hi], dtype=float), np.array([v, v]))

    def fit(self, scores: np.ndarray, iterations: int = 50) -> ScoreMixture:
        """``iterations`` EM steps from the current parameters (in place; returns self)."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        floor = _var_floor(s)
        for _ in range(int(iterations)):
            r = self.responsibility(s)  # (n,) of the target class
            n1 = r.sum()
            n0 = s.size - n1
            if n1 < 1e-9 or n0 < 1e-9:  # one class took everything: nothing to separate
                break
            m = np.array([((1 - r) * s).sum() / n0, (r * s).sum() / n1])
            v = np.array([((1 - r) * (s - m[0]) ** 2).sum() / n0,
                          (r * (s - m[1]) ** 2).sum() / n1])
            self.mean, self.var = m, np.maximum(v, floor)
            self.weight = float(n1 / s.size)
        if self.mean[0] > self.mean[1]:  # keep component 1 the higher one
            self.mean, self.var = self.mean[::-1].copy(), self.var[::-1].copy()
            self.weight = 1.0 - self.weight
        return self

    def log_densities(self, s: np.ndarray) -> np.ndarray:
        """``(n, 2)`` log-densities of the clutter (0) and target (1) components."""
        s = np.asarray(s, dtype=float).reshape(-1, 1)
        return -0.5 * (np.log(2 * np.pi * self.var) + (s - self.mean) ** 2 / self.var)

    def responsibility(self, s: np.ndarray) -> np.ndarray:
        """``P(target | s)`` under the mixture, ``(n,)``."""
        w = np.clip(self.weight, 1e-12, 1 - 1e-12)
        ld = self.log_densities(s)
        a = np.log(w) + ld[:, 1] - np.log1p(-w) - ld[:, 0]
        return 1.0 / (1.0 + np.exp(-np.clip(a, -700, 700)))

    def log_ratio(self, s: np.ndarray) -> np.ndarray:
        """``log f_T(s) / f_C(s)`` with ``s`` clipped to the span of the two means
        (monotone, saturating in the tails), ``(n,)``."""
        lo, hi = float(self.mean[0]), float(self.mean[1])
        ld = self.log_densities(np.clip(np.asarray(s, dtype=float), lo, hi))
        return ld[:, 1] - ld[:, 0]


def shadowed(boxes: np.ndarray, scores: np.ndarray, iou: float) -> np.ndarray:
    """``(M,)`` mask of the detections that overlap a higher-scored detection of the
    same frame by ``IoU ≥ iou`` (top-left ``(x, y, w, h)`` boxes; ties shadow neither).

    A detector's non-maximum suppression removes a box that overlaps a better one by
    more than its threshold (about 0.5 IoU for the shared sequences' public detections:
    the largest overlap of two boxes of one frame is 0.499 on MOT16-11, 0.484 on
    TUD-Campus, 0.493 on TUD-Stadtmitte, 0.508 on PETS09-S2L1, where 11 pairs exceed
    0.5); a second box on the same person — DPM's at the next pyramid
    level, √2 larger, or shifted onto the legs — survives just below it, with the lower
    score. Such a detection explains nothing a new target would: it may extend a
    tracked target, not start one.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    s = np.asarray(scores, dtype=float).reshape(-1)
    if b.shape[0] < 2 or iou <= 0:
        return np.zeros(b.shape[0], dtype=bool)
    overlap = iou_xywh(b[:, None, :], b[None, :, :])
    return np.any((overlap >= iou) & (s[None, :] > s[:, None]), axis=1)


def _var_floor(s: np.ndarray) -> float:
    """A variance floor in the scores' own units: (1 % of the interquartile range)²."""
    if s.size < 2:
        return 1e-12
    q1, q3 = np.quantile(s, [0.25, 0.75])
    return max((0.01 * float(q3 - q1)) ** 2, 1e-12)


class ScoreCalibration:
    """Online calibration of :class:`ScoreSettings` on one video (per-run state).

    Each frame: :meth:`observe` adds the frame's scores and refits (warm-started EM);
    :meth:`terms` gives each detection's factors on ``κ`` and ``ν_b`` (from
    :meth:`clutter_scale` and :meth:`birth_mask` for the literal model).
    Deterministic (no randomness).
    """

    def __init__(self, settings: ScoreSettings):
        self.settings = settings
        self._chunks: list[np.ndarray] = []
        self.count = 0
        self.frames = 0
        self.mixture: ScoreMixture | None = None
        #: the ``"learned"`` model: the video's score model, this frame's probabilities
        #: and the sum of every probability so far
        self.persistence = PersistenceScoreModel() if settings.model == "learned" else None
        self._p: np.ndarray | None = None
        self._p_sum = 0.0

    def observe(self, scores: np.ndarray, boxes: np.ndarray | None = None) -> None:
        """Add a frame's scores (and, for the ``"learned"`` model, its top-left ``(x, y,
        w, h)`` boxes) and refit."""
        if self.persistence is not None:
            self._observe_learned(scores, boxes)
            return
        s = np.asarray(scores, dtype=float).reshape(-1)
        s = s[np.isfinite(s)]
        self.frames += 1
        if s.size:
            self._chunks.append(s)
            self.count += s.size
        if self.count < self.settings.min_samples:
            return
        all_s = np.concatenate(self._chunks) if len(self._chunks) > 1 else self._chunks[0]
        self._chunks = [all_s]
        if self.mixture is None:
            self.mixture = ScoreMixture.initial(all_s).fit(all_s, 10 * self.settings.em_iter)
        elif s.size:
            self.mixture.fit(all_s, self.settings.em_iter)

    def _observe_learned(self, scores: np.ndarray, boxes: np.ndarray | None) -> None:
        if boxes is None:
            raise ValueError("the learned score model needs the detections' boxes")
        self._p = self.persistence.update(
            xywh_to_cxcywh(np.asarray(boxes, dtype=float).reshape(-1, 4)), scores)
        self.frames += 1
        self.count += self._p.size
        self._p_sum += float(self._p.sum())

    @property
    def ready(self) -> bool:
        if self.persistence is not None:
            return self.count >= self.settings.min_samples
        return self.mixture is not None

    def _share(self) -> float:
        """``π``: the target class's share of the video's detections so far."""
        if self.persistence is not None:
            return self._p_sum / max(self.count, 1)
        return float(self.mixture.weight)

    def _probability(self, s: np.ndarray) -> np.ndarray:
        """``P(target | s)`` of this frame's detections (the learned model: the
        probabilities of the frame just observed)."""
        if self.persistence is not None:
            if self._p is None or self._p.size != s.size:
                raise ValueError("the learned score model reads the frame it observed last")
            return self._p
        return self.mixture.responsibility(s)

    def clutter_scale(self, scores: np.ndarray) -> np.ndarray:
        """``(f_C(s) / f_T(s))^γ`` per detection, clipped (1 before the first fit)."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        if not self.ready:
            return np.ones(s.size)
        return np.exp(-self.settings.temper * self._log_ratio(s))

    def _log_ratio(self, s: np.ndarray) -> np.ndarray:
        """``log f_T(s)/f_C(s)``, clipped to ``± log max_ratio``: of the fitted mixture (a
        missing score reads as the clutter class's mean), or of the learned probability
        against the video's share of targets."""
        c = np.log(self.settings.max_ratio)
        if self.persistence is not None:
            p = np.clip(self._probability(s), 1e-9, 1 - 1e-9)
            pi = float(np.clip(self._share(), 1e-9, 1 - 1e-9))
            return np.clip(np.log(p / (1 - p)) - np.log(pi / (1 - pi)), -c, c)
        m = self.mixture
        return np.clip(m.log_ratio(np.nan_to_num(s, nan=m.mean[0])), -c, c)

    def terms(self, scores: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-detection factors ``(on κ, on ν_b)``.

        ``persisting="target"``: ``((f_C/f_T)^γ, birth mask)``. ``"all"``: the corrector
        divided by the marginal score density ``f = π f_T + (1 − π) f_C`` instead of
        ``f_T`` — ``((f_C/f)^γ, (f_T/f)^γ × birth mask)``.
        """
        s = np.asarray(scores, dtype=float).reshape(-1)
        mask = self.birth_mask(s).astype(float)
        if not self.ready:
            return np.ones(s.size), mask
        if self.settings.persisting == "target":
            return self.clutter_scale(s), mask
        lr = self._log_ratio(s)  # log f_T/f_C
        pi = float(np.clip(self._share(), 1e-12, 1 - 1e-12))
        log_f_over_fc = np.logaddexp(np.log(pi) + lr, np.log1p(-pi))  # log f/f_C
        g = self.settings.temper
        return np.exp(-g * log_f_over_fc), mask * np.exp(g * (lr - log_f_over_fc))

    def birth_mask(self, scores: np.ndarray) -> np.ndarray:
        """Which detections may spawn newborn particles (all before the first fit)."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        if not self.ready or self.settings.birth_min_prob <= 0:
            return np.ones(s.size, dtype=bool)
        return self._probability(s) >= self.settings.birth_min_prob

    def clutter_rate(self, default: float) -> float:
        """The calibrated ``λ_c`` (``default`` unless ``clutter_from_scores`` and fitted)."""
        if not (self.settings.clutter_from_scores and self.ready):
            return default
        return (1.0 - self._share()) * self.count / max(self.frames, 1)


def mid_ranks(sorted_scores: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """``(M,)`` each of ``scores`` as its mid-rank quantile in ``sorted_scores`` (sorted,
    ``n`` values): ``(#{< s} + #{≤ s}) / 2n``, in ``[0, 1]`` (0.5 for every score when
    ``n`` is 0). Any strictly increasing map of all the scores leaves it unchanged."""
    s = np.asarray(scores, dtype=float).reshape(-1)
    n = sorted_scores.size
    if n == 0:
        return np.full(s.size, 0.5)
    lo = np.searchsorted(sorted_scores, s, side="left")
    hi = np.searchsorted(sorted_scores, s, side="right")
    return (lo + hi) / (2.0 * n)


class ScoreQuantiles:
    """Each detection's score as its quantile among every score the video has shown so
    far, this frame's included (:func:`mid_ranks`): a threshold on it is a share of the
    sequence's detections ("the top 40 %"), the same for any strictly increasing map of
    the scores. Online and deterministic; one instance per video."""

    def __init__(self) -> None:
        self.seen = SortedScores()  # every score so far

    @property
    def history(self) -> np.ndarray:
        """Every finite score so far, sorted."""
        return self.seen.sorted()

    def update(self, boxes: np.ndarray, scores: np.ndarray) -> np.ndarray:
        """Add a frame's scores; returns their quantiles ``(M,)`` (NaN scores: 0)."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        if s.size != np.asarray(boxes).reshape(-1, 4).shape[0]:
            raise ValueError(f"{np.asarray(boxes).reshape(-1, 4).shape[0]} boxes but "
                             f"{s.size} scores")
        self.seen.add(s)
        if self.seen.size == 0:
            return np.zeros(s.size)
        return np.where(np.isfinite(s), self.seen.mid_ranks(s), 0.0)


#: how detection scores are brought to [0, 1] before the rounds' thresholds: ``"none"``
#: (as given), ``"logistic"`` (``1 / (1 + e^{-s})``: one monotone map for a detector whose
#: scores are margins or unbounded, as MOT15's and MOT16's public ones are), ``"constant"``
#: (every detection 1: a detector whose scores say nothing of confidence, such as
#: background subtraction's fill fractions — as the ``trackers`` package treats
#: detections without scores), ``"learned"`` (the probability that the detection is of a
#: target, learned on the video from which detections are found again and read from the
#: score's rank: :class:`PersistenceScoreModel`; the same for any strictly increasing
#: map of the detector's scores, so thresholds are statements about the detections, not
#: about a number on the detector's scale), ``"quantile"`` (the score's quantile among
#: the video's scores so far: a threshold is a share of the detections,
#: :class:`ScoreQuantiles`; the same for any such map), ``"quantile-gated"`` (that
#: quantile, 0 where the learned model shows the detections more likely clutter than of a
#: target: a lower detector threshold adds no detections a threshold lets through),
#: ``"quantile-rebased"`` (the quantile among the detections above it), ``"placed"`` (above that
#: clutter, the probability that a detection is on the tracked object it is near, learned
#: from the tracks; ``"placed-rebased"`` over the rebased quantile; ``"placed-over"`` lifted
#: below that clutter too), :class:`~pgm.factors.persistent_quantiles.PersistentQuantiles`
SCORE_MAPS = ("none", "logistic", "constant", "learned", "quantile", "quantile-gated",
              "quantile-rebased", "placed", "placed-rebased", "placed-over")
#: the score maps learned on the video (kept per run by the association rule)
LEARNED_SCORE_MAPS = SCORE_MAPS[3:]


def map_scores(scores: np.ndarray, score_map: str) -> np.ndarray:
    """``scores`` through the map ``score_map`` (:data:`SCORE_MAPS`)."""
    s = np.asarray(scores, dtype=float)
    if score_map == "none":
        return s
    if score_map == "logistic":
        return 0.5 * (1.0 + np.tanh(0.5 * s))  # the logistic, without overflow
    if score_map == "constant":
        return np.ones_like(s)
    if score_map in LEARNED_SCORE_MAPS:
        raise ValueError(f"the {score_map!r} score map is learned on the video: "
                         "pgm.factors.association.DetectionAssociation.score_model() keeps it per run")
    raise ValueError(f"unknown score map {score_map!r} (choose from {SCORE_MAPS})")
