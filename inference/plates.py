r"""The plate engine: one sub-graph per target, all replicas stepped in one batched pass.

A graph with a :class:`~pgm.core.plate.Plate` declares the model of *one* target; this
engine runs ``K`` replicas of it, ``K`` changing as tracks start and end. Each plate
variable's belief is kept as arrays with a leading target axis — particles ``(K, N, d)``,
normalised log-weights ``(K, N)``, histories ``(K, N, d)`` — and every stage acts on all
replicas at once:

* **predict** — a transition shared by the replicas samples the ``K·N`` particles in one
  call of ``factor.sample`` (particles flattened to ``(K·N, d)``);
* **weight** — a likelihood shared by the replicas (detections, a learned person model)
  scores all ``K·N`` particles in one call; a likelihood that learns a per-target
  template is copied per replica at its birth and the copies are scored together by
  ``log_likelihood_batch`` (one pass for colour histograms);
* **interaction** — factors between replicas (kind ``"interaction"``, e.g. mutual
  exclusion) reweight every replica's particles against the other replicas' current
  estimates, all ``(K, N, K)`` pairs in one array expression;
* **in-frame** — coupling messages between the parts of each replica (particle BP,
  mixture fusion with source weights: :mod:`pgm.inference.pbp`) for all replicas at
  once;
* **estimate, learn, resample** — weighted means ``(K, d)``; factors that learn are
  updated per replica; ESS-triggered resampling per replica.

**Randomness.** Each replica owns a ``numpy.random.Generator`` (given at its birth, else
spawned from the engine's), and a batched draw of shape ``(K·N, ...)`` is made of ``K``
draws of shape ``(N, ...)``, one from each replica's generator (:class:`ReplicaRNG`).
A replica therefore consumes its stream exactly as a single-target
:class:`~pgm.inference.Engine` run of the same graph would: ``K = 1`` reproduces that
engine bit for bit, and ``K`` replicas without interaction reproduce ``K`` separate
runs (tested). A factor whose ``sample``/``propagate`` draws numbers whose leading axis
is not the particle count cannot be split this way and is refused with its name.

**Births and deaths** follow the plate's :class:`~pgm.core.plate.Lifecycle`: after the
replicas are stepped, their boxes are matched to the frame's detections (Hungarian on
``1 − IoU``); a detection matching no replica starts one (its prior re-centred on the
detection, ``prior.born_at``; its templates learned from this frame; the first-frame
stages run on it), confirmed after ``confirm_hits`` matches; identities, coasting, the
lost stage and the existence score are those of :mod:`pgm.inference.tracks`.

The target's box is the bounding box of the output variables' boxes (one variable: its
box). New replicas' part boxes are placed relative to the detection as the prior means
of the declaration are placed relative to ``graph.meta["reference_box"]`` (default:
the bounding box of the output variables' prior means).

Limits: one plate per graph, every variable inside it (no shared *variables*: shared
parameters live in the factors' declarations); couplings use mixture fusion with
``message_weight="source"`` and one message particle per particle.

Example
-------
>>> import numpy as np
>>> from pgm.models import multi_pf
>>> g = multi_pf.build_graph(multi_pf.Params(num_particles=30))
>>> engine = PlateEngine(g, rng=np.random.default_rng(0))
>>> engine.num_targets
0
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from pgm.core.boxes import cxcywh_to_xywh, iou_xywh
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.motion import warp_states
from pgm.core.readout import Targets, register_readout
from pgm.factors import LikelihoodFactor

from .engine import StepRecord, message_order
from .resampling import ess_triggered, get_resampler
from .settings import EngineSettings
from .tracks import Track

__all__ = ["PlateEngine", "ReplicaRNG", "plate_boxes", "make_engine"]

_BOX = ("cx", "cy", "w", "h")


# -------------------------------------------------------------------------------------
# randomness split over replicas
# -------------------------------------------------------------------------------------
class ReplicaRNG:
    """A ``Generator`` look-alike whose draws split over replicas.

    A draw of ``size = (K·n, ...)`` is made of ``K`` draws of ``(n, ...)``, the ``k``-th
    from ``generators[k]``; array arguments (``loc``, ``scale``, ``low``, ``high``)
    whose leading axis is ``K·n`` are split the same way, others are passed to every
    replica. Only the methods the toolkit's factors use are offered.
    """

    def __init__(self, generators: Sequence[np.random.Generator], n: int,
                 owner: str = "a factor"):
        self.generators = list(generators)
        self.n = int(n)
        self.owner = owner

    @property
    def total(self) -> int:
        """``K·n``: the leading axis every draw must have."""
        return len(self.generators) * self.n

    def _sizes(self, size) -> tuple[int, ...]:
        shape = (size,) if np.ndim(size) == 0 and size is not None else tuple(size or ())
        if not shape or shape[0] != self.total:
            raise ValueError(
                f"{self.owner} drew random numbers of shape {shape}, whose leading axis is not "
                f"the particle count {self.total}; the plate engine splits draws per replica "
                f"along that axis (draw one value per particle, e.g. "
                f"rng.standard_normal((n, d)))")
        return (self.n,) + shape[1:]

    def _part(self, value, k: int):
        if np.ndim(value) > 0 and np.shape(value)[0] == self.total:
            return value[k * self.n:(k + 1) * self.n]
        return value

    def _draw(self, method: str, size, *args, out=None):
        if out is not None:
            size = out.shape
        per = self._sizes(size)
        parts = [getattr(g, method)(*(self._part(a, k) for a in args), size=per)
                 for k, g in enumerate(self.generators)]
        res = np.concatenate(parts) if parts else np.zeros((0,) + per[1:])
        if out is not None:
            out[...] = res
            return out
        return res

    def standard_normal(self, size=None, dtype=np.float64, out=None):
        """Standard normal draws, split over replicas."""
        return self._draw("standard_normal", size, out=out)

    def random(self, size=None, dtype=np.float64, out=None):
        """Uniform [0, 1) draws, split over replicas."""
        return self._draw("random", size, out=out)

    def normal(self, loc=0.0, scale=1.0, size=None):
        """Normal draws, split over replicas."""
        if size is None:
            size = np.broadcast(np.asarray(loc), np.asarray(scale)).shape
        return self._draw("normal", size, loc, scale)

    def uniform(self, low=0.0, high=1.0, size=None):
        """Uniform draws, split over replicas."""
        if size is None:
            size = np.broadcast(np.asarray(low), np.asarray(high)).shape
        return self._draw("uniform", size, low, high)

    def __getattr__(self, name: str):
        raise ValueError(f"{self.owner} calls rng.{name}(), which the plate engine cannot "
                         f"split per replica (use standard_normal, random, normal or uniform "
                         f"with one draw per particle)")


# -------------------------------------------------------------------------------------
# boxes of a plate model
# -------------------------------------------------------------------------------------
def _box_columns(graph: FactorGraph, variable: str) -> list[int]:
    v = graph.variables[variable]
    if v.labels is None or not all(b in v.labels for b in _BOX):
        raise ValueError(f"plate variable {variable!r} must have the labels cx, cy, w, h "
                         f"(a box), got {v.labels}")
    return [v.labels.index(b) for b in _BOX]


def _bounding(boxes: list[np.ndarray]) -> np.ndarray:
    """Bounding box ``(..., 4)`` (cx, cy, w, h) of several boxes of the same shape."""
    if len(boxes) == 1:
        return boxes[0]
    b = np.stack(boxes)
    x0 = (b[..., 0] - b[..., 2] / 2).min(0)
    x1 = (b[..., 0] + b[..., 2] / 2).max(0)
    y0 = (b[..., 1] - b[..., 3] / 2).min(0)
    y1 = (b[..., 1] + b[..., 3] / 2).max(0)
    return np.stack([(x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0], axis=-1)


def plate_boxes(graph: FactorGraph, estimates: dict[str, np.ndarray]) -> np.ndarray:
    """The targets' boxes ``(K, 4)`` (cx, cy, w, h): the bounding box of the output
    variables' boxes in ``estimates`` (each ``(K, d)``)."""
    return _bounding([np.asarray(estimates[v])[..., _box_columns(graph, v)]
                      for v in graph.output])


# -------------------------------------------------------------------------------------
# the replicas' state
# -------------------------------------------------------------------------------------
@dataclass
class _Batch:
    """Beliefs and per-replica objects of ``K`` replicas (leading axis ``K``)."""

    x: dict[str, np.ndarray] = field(default_factory=dict)
    lw: dict[str, np.ndarray] = field(default_factory=dict)
    hist: dict[str, tuple[np.ndarray, ...]] = field(default_factory=dict)
    rngs: list[np.random.Generator] = field(default_factory=list)
    local: dict[str, list] = field(default_factory=dict)
    tracks: list[Track] = field(default_factory=list)
    est: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def K(self) -> int:  # noqa: N802 - the plate's size is called K
        return len(self.rngs)

    def select(self, keep: np.ndarray) -> _Batch:
        idx = np.flatnonzero(keep)
        return _Batch({v: a[idx] for v, a in self.x.items()},
                      {v: a[idx] for v, a in self.lw.items()},
                      {v: tuple(h[idx] for h in hs) for v, hs in self.hist.items()},
                      [self.rngs[i] for i in idx],
                      {n: [fs[i] for i in idx] for n, fs in self.local.items()},
                      [self.tracks[i] for i in idx],
                      {v: a[idx] for v, a in self.est.items()})

    @staticmethod
    def join(a: _Batch, b: _Batch) -> _Batch:
        if a.K == 0:
            return b
        if b.K == 0:
            return a
        cat = np.concatenate
        return _Batch({v: cat([a.x[v], b.x[v]]) for v in a.x},
                      {v: cat([a.lw[v], b.lw[v]]) for v in a.lw},
                      {v: tuple(cat([h, g]) for h, g in zip(a.hist[v], b.hist[v], strict=True))
                       for v in a.hist},
                      a.rngs + b.rngs,
                      {n: a.local[n] + b.local[n] for n in a.local},
                      a.tracks + b.tracks,
                      {v: cat([a.est[v], b.est[v]]) for v in a.est})


def _log_mass(lw: np.ndarray) -> np.ndarray:
    """Per-row ``logsumexp`` of ``(K, N)`` log-weights, computed as
    :func:`pgm.core.numerics.logsumexp` computes one row (so one replica's numbers are
    those of a single-target run, to the last bit)."""
    m = lw.max(axis=1) if lw.shape[1] else np.full(lw.shape[0], -np.inf)
    finite = np.isfinite(m)
    safe = np.where(finite, m, 0.0)
    e = np.exp(lw - safe[:, None])
    # row by row: numpy's axis-1 reduction may round differently from a 1-D sum
    return np.array([mk + math.log(float(row.sum())) if ok else -np.inf
                     for mk, row, ok in zip(m.tolist(), e, finite.tolist(), strict=True)])


def _row_normalize(lw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-row normalisation of ``(K, N)`` log-weights; returns (normalised, log mass).
    Rows with no finite weight are returned unchanged (their log mass is ``-inf``)."""
    lm = _log_mass(lw)
    return lw - np.where(np.isfinite(lm), lm, 0.0)[:, None], lm


def _row_log_normalize(lw: np.ndarray) -> np.ndarray:
    """Per-row :func:`pgm.core.numerics.log_normalize` (the same arithmetic per row)."""
    m = lw.max(axis=1, keepdims=True)
    shifted = lw - m
    e = np.exp(shifted)
    return shifted - np.array([math.log(float(row.sum())) for row in e])[:, None]


def _weights(lw: np.ndarray) -> np.ndarray:
    """Normalised weights of rows of *normalised* log-weights, as
    :attr:`pgm.core.beliefs.Particles.weights` computes them for a normalised belief
    (whose log mass is known to be 0)."""
    w = np.exp(lw)
    return w / np.array([row.sum() for row in w])[:, None]


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of centre boxes ``a`` and ``b``, broadcasting over the leading axes."""
    return iou_xywh(cxcywh_to_xywh(a), cxcywh_to_xywh(b))


class PlateEngine:
    """Runs a graph with a plate over a video: ``K`` replicas, batched.

    Parameters
    ----------
    graph : FactorGraph
        A graph with one :class:`~pgm.core.plate.Plate` holding all its variables.
    rng : numpy.random.Generator
        Source of the replicas' generators (each spawned from it at the replica's birth
        unless :meth:`add` is given generators).
    settings, num_particles, resampling, ess_threshold :
        As for :class:`~pgm.inference.Engine`.
    """

    def __init__(self, graph: FactorGraph, rng: np.random.Generator, *,
                 settings: EngineSettings | None = None,
                 num_particles: int | dict[str, int] | None = None,
                 resampling: str | None = None, ess_threshold: float | None = None,
                 **unused: Any):
        if not isinstance(graph, FactorGraph):
            raise ValueError(f"PlateEngine needs a FactorGraph, got {type(graph).__name__}")
        if not graph.plates:
            raise ValueError(f"graph {graph.name!r} declares no plate; run it with Engine")
        if not isinstance(rng, np.random.Generator):
            raise ValueError("PlateEngine needs rng=numpy.random.Generator")
        bad = sorted(k for k, v in unused.items() if v is not None)
        if bad:
            raise ValueError(f"PlateEngine does not take {bad}")
        self.graph = copy.deepcopy(graph)
        self.template = copy.deepcopy(graph)  # factors as declared: copied per new replica
        self.rng = rng
        self.plate = self.graph.plates[0]
        outside = [v for v in self.graph.variables if v not in self.plate.variables]
        if outside:
            raise ValueError(f"graph {graph.name!r}: variables {outside} are outside the plate "
                             f"{self.plate.name!r}; the plate engine runs graphs whose every "
                             f"variable is in the plate (shared parameters belong in factors)")
        if settings is None:
            settings = EngineSettings.from_dict(self.graph.meta.get("engine"))
        self.settings = settings.replace(num_particles=num_particles, resampling=resampling,
                                         ess_threshold=ess_threshold)
        if self.settings.fusion != "mixture" or self.settings.message_weight != "source":
            raise ValueError("the plate engine fuses part messages as a mixture with source "
                             "weights (fusion='mixture', message_weight='source')")
        self.graph.meta["engine"] = self.settings.to_dict(full=True)
        counts = self.settings.num_particles
        self.num_particles = {v: int(counts.get(v, EngineSettings.num_particles)
                                     if isinstance(counts, dict) else counts)
                              for v in self.graph.variables}
        if self.settings.message_particles not in (None, *self.num_particles.values()):
            raise ValueError("the plate engine sends one message particle per particle "
                             "(message_particles must be unset)")
        self.resampler = get_resampler(self.settings.resampling)
        self.ess_threshold = self.settings.ess_threshold
        g = self.graph
        for v in g.variables.values():
            if v.role not in ("part", "state", "latent"):
                raise ValueError(f"plate variable {v.name!r} has role {v.role!r}; the plate "
                                 f"engine keeps particle beliefs (part, state, latent)")
            if len(g.factors_of(v.name, "prior")) != 1:
                raise ValueError(f"plate variable {v.name!r} needs one prior factor")
            _box_columns(g, v.name)
        self.priors = [f for f in g.factors.values() if f.kind == "prior"]
        self.learners = [f for f in g.factors.values() if f.learns]
        self.transitions = {f.variables[0]: f for f in g.factors_by_kind("transition")}
        self.likelihoods = g.factors_by_kind("likelihood")
        self.interactions = g.factors_by_kind("interaction")
        self.messages = message_order(g, "mixture")
        self.couplings = g.factors_by_kind("coupling")
        for f in g.factors_by_kind("conjugate"):
            raise ValueError(f"conjugate factor {f.name!r}: the plate engine has no VB stage")
        self.receivers = [v for v in g.variables if any(d == v for _, _, d in self.messages)]
        self._groups = self._weight_groups()
        #: factors copied per replica (they learn per target), by name
        self.per_replica = [f.name for f in g.factors.values() if f.kind != "prior"
                            and (f.learns or (isinstance(f, LikelihoodFactor) and
                                              type(f).initialize is not
                                              LikelihoodFactor.initialize))]
        ref = g.meta.get("reference_box")
        means = {f.variables[0]: np.asarray(f.mean(), dtype=float) for f in self.priors}
        self.reference_box = (np.asarray(ref, dtype=float) if ref is not None else
                              plate_boxes(g, {v: m[None] for v, m in means.items()})[0])
        self._prior_boxes = {v: m[_box_columns(g, v)] for v, m in means.items()}
        self.batch = _Batch()
        self._next_id = 1
        self.t = 0
        self.frame: FrameContext | None = None

    # -- queries -----------------------------------------------------------------------
    @property
    def num_targets(self) -> int:
        """Number of replicas ``K`` (tentative, confirmed and lost)."""
        return self.batch.K

    @property
    def tracks(self) -> list[Track]:
        """The replicas' track records (identities, hits, existence), in replica order."""
        return list(self.batch.tracks)

    def beliefs(self, variable: str) -> tuple[np.ndarray, np.ndarray]:
        """Particles ``(K, N, d)`` and normalised log-weights ``(K, N)`` of ``variable``."""
        return self.batch.x[variable], self.batch.lw[variable]

    def factor(self, name: str, replica: int):
        """The factor ``name`` as replica ``replica`` uses it (its own copy if it learns)."""
        local = self.batch.local.get(name)
        return local[replica] if local is not None else self.graph.factors[name]

    # -- births and deaths ------------------------------------------------------------
    def _part_values(self, box: np.ndarray) -> dict[str, dict[str, float]]:
        """Each variable's box for a target whose box is ``box`` (cx, cy, w, h)."""
        ref = self.reference_box
        sw, sh = box[2] / ref[2], box[3] / ref[3]
        out = {}
        for v, p in self._prior_boxes.items():
            out[v] = {"cx": box[0] + (p[0] - ref[0]) * sw, "cy": box[1] + (p[1] - ref[1]) * sh,
                      "w": p[2] * sw, "h": p[3] * sh}
        return out

    def add(self, boxes: np.ndarray, frame: FrameContext,
            rngs: Sequence[np.random.Generator] | None = None,
            confirmed: bool = False) -> list[int]:
        """Start replicas on ``boxes`` ``(M, 4)`` (cx, cy, w, h) in ``frame``.

        Each replica's prior is re-centred on its box; its templates are learned from
        ``frame``; it is weighted, estimated and resampled there as a single-target
        engine treats its first frame. ``rngs`` gives each replica its generator
        (default: spawned from the engine's). ``confirmed`` starts them with identities
        (e.g. targets given by the user). Returns their indices.
        """
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        if not np.all(np.isfinite(boxes)) or np.any(boxes[:, 2:] <= 0):
            raise ValueError("replica boxes must be finite with positive width and height")
        m = len(boxes)
        if rngs is None:
            rngs = self.rng.spawn(m) if m else []
        rngs = list(rngs)
        if len(rngs) != m:
            raise ValueError(f"{m} boxes but {len(rngs)} generators")
        if m == 0:
            return []
        g = self.graph
        nb = _Batch(rngs=rngs)
        xs: dict[str, list[np.ndarray]] = {v: [] for v in g.variables}
        born: dict[str, list] = {}
        for box, r in zip(boxes, rngs, strict=True):
            values = self._part_values(box)
            for f in self.priors:  # declaration order, as the engine's prior stage
                v = f.variables[0]
                prior = f.born_at(values[v], g.variables[v].labels)
                xs[v].append(np.asarray(prior.sample(r, self.num_particles[v]), dtype=float))
                born.setdefault(v, []).append(prior)
        for v in g.variables:
            n = self.num_particles[v]
            nb.x[v] = np.stack(xs[v]).reshape(m, n, -1)
            nb.lw[v] = np.full((m, n), -np.log(n))
            tr = self.transitions.get(v)
            h = max(0, getattr(tr, "order", 1) - 1) if tr is not None else 0
            nb.hist[v] = tuple(nb.x[v].copy() for _ in range(h))
        for name in self.per_replica:
            nb.local[name] = [copy.deepcopy(self.template.factors[name]) for _ in range(m)]
        for f in self.likelihoods:  # templates learned at the prior mean, as the engine
            v = f.variables[0]
            for k in range(m):
                self._local(nb, f.name, k).initialize(frame, born[v][k].mean())
        for box in boxes:
            t = Track(np.asarray(box, dtype=float).copy())
            if confirmed:
                t.track_id = self._next_id
                self._next_id += 1
            nb.tracks.append(t)
        self._tail(nb, frame, {}, interact=False)
        first = self.batch.K
        self.batch = _Batch.join(self.batch, nb)
        return list(range(first, first + m))

    def remove(self, indices: Sequence[int]) -> None:
        """Remove the replicas at ``indices``."""
        keep = np.ones(self.batch.K, dtype=bool)
        keep[np.asarray(list(indices), dtype=int)] = False
        self.batch = self.batch.select(keep)

    # -- one frame ----------------------------------------------------------------------
    def step(self, frame: FrameContext, *, lifecycle: bool = True) -> StepRecord:
        """Step every replica through ``frame``; then births and deaths from its detections
        (``lifecycle=False``: none, e.g. for targets managed by the caller).

        A frame with neither image nor detections is *missing*: the replicas are only
        predicted (no weighting, learning, resampling, births or deaths) and their
        predicted boxes reported."""
        if not isinstance(frame, FrameContext):
            raise ValueError(f"step() needs a FrameContext, got {type(frame).__name__}")
        self.frame = frame
        record = StepRecord(frame=frame.index)
        info: dict[str, Any] = {}
        b = self.batch
        missing = frame.image is None and frame.detections is None
        if b.K:
            self._predict(b, frame)
            if missing:  # a missing frame: prediction only, the chains go on
                for v in self.graph.variables:
                    b.est[v] = self._means(b, v)
            else:
                self._tail(b, frame, info, interact=True)
        if lifecycle and not missing:
            self._lifecycle(frame, info)
        info["missing"] = missing
        b = self.batch
        for v in self.graph.variables:
            record.estimates[v] = b.est.get(v, np.zeros((0, self.graph.variables[v].dim)))
        boxes = (plate_boxes(self.graph, b.est) if b.K else np.zeros((0, 4)))
        lc = self.plate.lifecycle
        reported = np.array([t.track_id is not None and t.misses <= lc.max_coast
                             and not t.recovering for t in b.tracks], dtype=bool)
        info.update(ids=np.array([t.track_id or 0 for t in b.tracks], dtype=np.int64),
                    boxes=boxes, reported=reported,
                    existence=np.array([t.existence for t in b.tracks], dtype=float))
        record.info[self.plate.name] = info
        self.t += 1
        return record

    def _local(self, b: _Batch, name: str, k: int):
        local = b.local.get(name)
        return local[k] if local is not None else self.graph.factors[name]

    def _predict(self, b: _Batch, frame: FrameContext) -> None:
        g = self.graph
        for v, f in self.transitions.items():
            x, hist = b.x[v], b.hist[v]
            K, n, d = x.shape  # noqa: N806
            labels = g.variables[v].labels
            flat = x.reshape(K * n, d)
            past = [h.reshape(K * n, d) for h in hist]
            if frame.camera_motion is not None:
                flat = warp_states(flat, labels, frame.camera_motion)
                past = [warp_states(h, labels, frame.camera_motion) for h in past]
            if f.name in b.local:  # a transition that learns per target: one call each
                new = np.concatenate([
                    np.asarray(b.local[f.name][k].sample(
                        b.rngs[k], flat[k * n:(k + 1) * n], *(h[k * n:(k + 1) * n]
                                                              for h in past)), dtype=float)
                    for k in range(K)])
            else:
                rng = ReplicaRNG(b.rngs, n, owner=f"transition {f.name!r}")
                new = np.asarray(f.sample(rng, flat, *past), dtype=float)
            if new.shape != flat.shape:
                raise ValueError(f"factor {f.name!r}: sample() returned shape {new.shape}, "
                                 f"expected {flat.shape}")
            n_hist = max(0, getattr(f, "order", 1) - 1)
            b.hist[v] = tuple(a.reshape(K, n, d) for a in ([flat] + past)[:n_hist])
            b.x[v] = new.reshape(K, n, d)

    def _weight_groups(self) -> list[list]:
        """Likelihood factors grouped as the single-target engine groups them: those with
        equal ``(type, batch_key)`` are scored in one ``log_likelihood_batch`` pass."""
        groups: list[list] = []
        by_key: dict[Any, list] = {}
        for f in self.likelihoods:
            key = f.batch_key
            if key is None:
                groups.append([f])
                continue
            key = (type(f), key)
            if key not in by_key:
                by_key[key] = []
                groups.append(by_key[key])
            by_key[key].append(f)
        return groups

    def _log_likelihoods(self, b: _Batch, fs: list, frame: FrameContext) -> list[np.ndarray]:
        """``(K, N)`` log-likelihoods of each factor in ``fs`` (one group)."""
        K = b.K  # noqa: N806
        shared = [f.name not in b.local for f in fs]
        pairs = K * len(fs)
        if pairs > 1 and fs[0].batch_key is not None and not any(shared):
            # the copies of the group's factors scored together, one pass per cluster of
            # replicas whose particles' boxes overlap (a joint pass costs the area of its
            # boxes' union, so distant targets are not scored through the empty space
            # between them); replica-major, so that one replica's order is the
            # single-target engine's
            out = [np.empty(b.lw[f.variables[0]].shape) for f in fs]
            for members in _clusters(self._extents(b, fs)):
                copies = [b.local[f.name][k] for k in members for f in fs]
                xs = [b.x[f.variables[0]][k] for k in members for f in fs]
                lls = type(fs[0]).log_likelihood_batch(copies, xs, frame)
                for i, ll in enumerate(lls):
                    out[i % len(fs)][members[i // len(fs)]] = ll
            return out
        out = []
        for f in fs:
            x = b.x[f.variables[0]]
            _, n, d = x.shape
            if f.name not in b.local:  # shared: all replicas' particles in one call
                out.append(np.asarray(f.log_likelihood(x.reshape(K * n, d), frame),
                                      dtype=float).reshape(K, n))
            else:
                out.append(np.stack([np.asarray(fk.log_likelihood(x[k], frame), dtype=float)
                                     for k, fk in enumerate(b.local[f.name])]))
        return out

    def _extents(self, b: _Batch, fs: list) -> np.ndarray:
        """``(K, 4)`` rectangles ``x0, y0, x1, y1`` around every particle's box of the
        group ``fs`` in each replica."""
        lo, hi = [], []
        for f in fs:
            c = _box_columns(self.graph, f.variables[0])
            bx = b.x[f.variables[0]][..., c]  # (K, N, 4) cx, cy, w, h
            lo.append((bx[..., :2] - np.abs(bx[..., 2:]) / 2).min(axis=1))
            hi.append((bx[..., :2] + np.abs(bx[..., 2:]) / 2).max(axis=1))
        return np.concatenate([np.min(lo, axis=0), np.max(hi, axis=0)], axis=1)

    def _tail(self, b: _Batch, frame: FrameContext, info: dict, *, interact: bool) -> None:
        """weight → interaction → in-frame → fuse → estimate → learn → resample."""
        g = self.graph
        evidence: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for fs in self._groups:
            for f, ll in zip(fs, self._log_likelihoods(b, fs, frame), strict=True):
                v = f.variables[0]
                if ll.shape != b.lw[v].shape:
                    raise ValueError(f"factor {f.name!r}: log_likelihood returned "
                                     f"{ll.size} values, expected {b.lw[v].shape[1]} per "
                                     f"replica")
                ll = np.where(np.isnan(ll), -np.inf, ll)
                lw0, tot = evidence.get(v, (b.lw[v], None))
                evidence[v] = (lw0, ll if tot is None else tot + ll)
        for v, (lw0, ll) in evidence.items():
            new, lm = _row_normalize(lw0 + ll)
            bad = ~np.isfinite(lm)  # no particle explains the frame: keep the prediction
            if bad.any():
                new[bad] = lw0[bad]
                info.setdefault("degenerate", {})[v] = np.flatnonzero(bad)
            b.lw[v] = new
        if interact and b.K > 1:
            for f in self.interactions:
                v = f.variables[0]
                est = self._means(b, v)
                pot = np.asarray(f.log_potential(b.x[v], est, frame), dtype=float)
                new, lm = _row_normalize(b.lw[v] + pot)
                ok = np.isfinite(lm)
                b.lw[v] = np.where(ok[:, None], new, b.lw[v])
                if v in evidence:
                    lw0, ll = evidence[v]
                    evidence[v] = (lw0, ll + pot)
        fused: dict[str, list[tuple[np.ndarray, np.ndarray, tuple]]] = {}
        for name, src, dst in self.messages:
            f = g.factors[name]
            x = b.x[src]
            K, n, d = x.shape  # noqa: N806
            flat = x.reshape(K * n, d)
            if name in b.local:
                x_msg = np.concatenate([np.asarray(b.local[name][k].propagate(
                    b.rngs[k], flat[k * n:(k + 1) * n], src)) for k in range(K)])
            else:
                x_msg = np.asarray(f.propagate(ReplicaRNG(b.rngs, n, owner=f"coupling {name!r}"),
                                               flat, src), dtype=float)
            d_dst = b.x[dst].shape[2]
            x_msg = x_msg.reshape(K, n, d_dst)
            n_hist = len(b.hist[dst])
            hist = [np.asarray(f.map(h.reshape(K * n, d), src)).reshape(K, n, d_dst)
                    for h in b.hist[src][:n_hist]]
            hist += [x_msg.copy() for _ in range(n_hist - len(hist))]
            lw0, ll = evidence.get(src, (b.lw[src], np.zeros_like(b.lw[src])))
            fused.setdefault(dst, []).append((x_msg, lw0 + ll, tuple(hist)))
        for v in self.receivers:
            lw0, ll = evidence.get(v, (b.lw[v], np.zeros_like(b.lw[v])))
            parts = [(b.x[v], lw0 + ll, b.hist[v])] + fused.get(v, [])
            b.lw[v] = _row_log_normalize(np.concatenate([p[1] for p in parts], axis=1))
            b.x[v] = np.concatenate([p[0] for p in parts], axis=1)
            b.hist[v] = tuple(np.concatenate([p[2][i] for p in parts], axis=1)
                              for i in range(len(b.hist[v])))
        for v in g.variables:
            b.est[v] = self._means(b, v)
        learners = self.learners
        if learners:
            for k in range(b.K):
                est = {v: b.est[v][k] for v in g.variables}
                scores = {}
                for v in g.variables:
                    fs = [self._local(b, f.name, k) for f in self.likelihoods
                          if f.variables[0] == v]
                    if fs:
                        xv = est[v].reshape(1, -1)
                        scores[v] = float(sum(fk.log_likelihood(xv, frame)[0] for fk in fs))
                for f in learners:
                    self._local(b, f.name, k).update(est, scores, frame)
        for v in g.variables:
            self._resample(b, v, info)

    def _means(self, b: _Batch, v: str) -> np.ndarray:
        w = _weights(b.lw[v])
        return np.stack([w[k] @ b.x[v][k] for k in range(b.K)]) if b.K else \
            np.zeros((0, b.x[v].shape[2]))

    def _resample(self, b: _Batch, v: str, info: dict) -> None:
        n = self.num_particles[v]
        x, lw = b.x[v], b.lw[v]
        if not b.K:
            return
        w = _weights(lw)
        fused = x.shape[1] != n
        ess = np.array([1.0 / float(np.dot(wk, wk)) for wk in w])
        pick = np.arange(b.K) if fused else np.array(
            [k for k in range(b.K) if ess_triggered(float(ess[k]), x.shape[1],
                                                    self.ess_threshold)], dtype=int)
        info.setdefault("ess", {})[v] = ess
        info.setdefault("resampled", {})[v] = np.isin(np.arange(b.K), pick)
        if not len(pick):
            return
        idx = np.stack([self.resampler(b.rngs[k], w[k], n) for k in pick])
        rows = pick[:, None]
        if fused:
            b.x[v] = x[rows, idx]
            b.hist[v] = tuple(h[rows, idx] for h in b.hist[v])
            b.lw[v] = np.full((b.K, n), -np.log(n))
            return
        b.x[v] = x.copy()
        b.x[v][pick] = x[rows, idx]
        b.hist[v] = tuple(_assign_rows(h, pick, h[rows, idx]) for h in b.hist[v])
        b.lw[v] = lw.copy()
        b.lw[v][pick] = -np.log(n)

    # -- the track layer -----------------------------------------------------------------
    def _lifecycle(self, frame: FrameContext, info: dict) -> None:
        lc = self.plate.lifecycle
        dets = frame.detections
        if dets is None:
            det_boxes = np.zeros((0, 4))
            scores = np.zeros(0)
        else:
            d = np.asarray(dets.boxes, dtype=float).reshape(-1, 4)
            det_boxes = np.column_stack([d[:, 0] + d[:, 2] / 2, d[:, 1] + d[:, 3] / 2,
                                         d[:, 2], d[:, 3]])
            scores = np.asarray(dets.scores, dtype=float)
        b = self.batch
        boxes = plate_boxes(self.graph, b.est) if b.K else np.zeros((0, 4))
        iou = _iou(boxes[:, None, :], det_boxes[None, :, :])
        matched: dict[int, int] = {}
        for group in (lambda t: t.misses <= lc.max_coast, lambda t: t.misses > lc.max_coast):
            rows_ok = [k for k, t in enumerate(b.tracks) if group(t) and k not in matched]
            cols_ok = [j for j in range(len(det_boxes)) if j not in matched.values()]
            if not rows_ok or not cols_ok:
                continue
            sub = iou[np.ix_(rows_ok, cols_ok)]
            r, c = linear_sum_assignment(-sub)
            for i, j in zip(r, c, strict=True):
                if sub[i, j] >= lc.match_iou:
                    matched[rows_ok[i]] = cols_ok[j]
        keep = np.ones(b.K, dtype=bool)
        for k, t in enumerate(b.tracks):
            t.age += 1
            if k in matched:
                if t.misses > lc.max_coast and t.track_id is not None:
                    t.recovering, t.streak = True, 0
                t.hit(lc.confirm_hits, lc.hit_log_odds)
                t.state = det_boxes[matched[k]].copy()
            else:
                t.miss(lc.miss_log_odds)
                if t.track_id is None or t.misses > lc.max_lost:
                    keep[k] = False
            if t.track_id is None and t.hits >= lc.confirm_hits and keep[k]:
                t.track_id = self._next_id
                self._next_id += 1
        used = set(matched.values())
        free = [j for j in range(len(det_boxes)) if j not in used
                and scores[j] >= lc.birth_min_score
                and (not b.K or iou[:, j].max() < lc.birth_iou)]
        # the free detections must not overlap each other either (one birth per person)
        births: list[int] = []
        for j in sorted(free, key=lambda j: -scores[j]):
            if all(_iou(det_boxes[j], det_boxes[i]) < lc.birth_iou for i in births):
                births.append(j)
        info["deaths"] = np.array([b.tracks[k].track_id or 0 for k in np.flatnonzero(~keep)],
                                  dtype=np.int64)
        self.batch = b.select(keep)
        info["births"] = len(births)
        if births:
            self.add(det_boxes[sorted(births)], frame)


def _clusters(rects: np.ndarray) -> list[list[int]]:
    """Groups of indices of rectangles ``(K, 4)`` (x0, y0, x1, y1) connected by overlap,
    each group in increasing order, groups by their first member."""
    k = len(rects)
    if k == 0:
        return []
    ov = ((rects[:, None, 0] < rects[None, :, 2]) & (rects[None, :, 0] < rects[:, None, 2])
          & (rects[:, None, 1] < rects[None, :, 3]) & (rects[None, :, 1] < rects[:, None, 3]))
    from scipy.sparse.csgraph import connected_components

    _, label = connected_components(ov, directed=False)
    groups: dict[int, list[int]] = {}
    for i, lab in enumerate(label.tolist()):
        groups.setdefault(lab, []).append(i)
    return sorted(groups.values(), key=lambda g: g[0])


def _assign_rows(a: np.ndarray, rows: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = a.copy()
    out[rows] = values
    return out


def make_engine(graph: FactorGraph, rng: np.random.Generator, **kwargs: Any):
    """The engine that runs ``graph``: :class:`PlateEngine` for a graph with a plate, else
    :class:`~pgm.inference.Engine` (keyword arguments passed on)."""
    if isinstance(graph, FactorGraph) and graph.plates:
        return PlateEngine(graph, rng, **kwargs)
    from .engine import Engine

    return Engine(graph, rng, **kwargs)


@register_readout("plate")
def plate_targets(graph: FactorGraph, record: StepRecord) -> Targets:
    """The replicas a plate engine's step reports (confirmed, not lost): identities,
    boxes and existence scores (the ``"plate"`` readout)."""
    info = record.info[graph.plates[0].name]
    keep = info["reported"]
    return Targets(info["ids"][keep], cxcywh_to_xywh(info["boxes"][keep]),
                   info["existence"][keep], text=f"{int(keep.sum())} targets")
