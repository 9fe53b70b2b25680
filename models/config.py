"""What a model config declares to the application: its options, its video defaults.

Every model module declares one :class:`ModelConfig` as ``CONFIG``: its name, what it
tracks (one object, many targets, or no video at all), the command-line options that set
its ``Params`` (:class:`Option`), and how it builds its graph for a video
(:meth:`ModelConfig.graph_for`: the video's size and frame rate, the initial box, the
detections' typical height). The application layer (``pgm track``, ``pgm graph``,
``pgm bench``) knows no model by name: it finds configs through the ``pgm.models`` entry
points (:func:`pgm.models.registry`) — the toolkit's own and those of any installed
package — and asks them.

A model in your own package:

.. code-block:: toml

    [project.entry-points."pgm.models"]
    my-tracker = "my_package.my_tracker:CONFIG"

>>> from pgm.models import colour_pf
>>> colour_pf.CONFIG.name, colour_pf.CONFIG.kind
('colour-pf', 'single-object')
>>> [o.flag for o in colour_pf.CONFIG.options]
['--appearance', '--scale-noise']
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Option", "VideoInfo", "ModelConfig", "KINDS", "int_in", "on_off", "finite_float",
           "default_build", "given", "APPEARANCE", "SCALE_NOISE", "PARTS"]

#: what a model tracks: one object given by a box, many targets from detections, or no
#: video at all (a state-space model fed measurements through the Python API)
KINDS = ("single-object", "multi-target", "state-space")


def int_in(flag: str, low: int, high: int) -> Callable[[str], int]:
    """An option type: an integer in ``[low, high]`` (a ``ValueError`` naming ``flag``)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except (TypeError, ValueError):
            raise ValueError(f"{flag} must be an integer, got {text!r}") from None
        if not low <= value <= high:
            raise ValueError(f"{flag} must be in [{low}, {high}], got {value}")
        return value

    parse.__name__ = "integer"
    return parse


def on_off(flag: str) -> Callable[[str], int]:
    """An option type: ``on`` or ``off`` as 1 or 0 (a number, so that ``off`` is *given*
    and turns a model's default off; a ``ValueError`` naming ``flag`` otherwise)."""
    def parse(text: str) -> int:
        if text not in ("on", "off"):
            raise ValueError(f"{flag} takes on or off, got {text!r}")
        return int(text == "on")
    return parse


def finite_float(flag: str) -> Callable[[str], float]:
    """An option type: a finite number (a ``ValueError`` naming ``flag``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except (TypeError, ValueError):
            raise ValueError(f"{flag} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise ValueError(f"{flag} must be finite, got {text!r}")
        return value

    parse.__name__ = "number"
    return parse


@dataclass(frozen=True)
class Option:
    """One command-line option of a model: ``flag`` sets ``Params.<field>``.

    ``type`` parses the text (a ``ValueError`` naming the flag on a bad value);
    ``choices`` limits it; ``flag_only`` is an on/off switch (``store_true``). ``field``
    ``None`` marks an option that the model's :attr:`ModelConfig.build` reads itself.
    """

    flag: str
    field: str | None
    help: str
    type: Callable[[str], Any] | None = None
    choices: tuple[str, ...] | None = None
    metavar: str | None = None
    flag_only: bool = False

    @property
    def dest(self) -> str:
        """The attribute name argparse gives the option (``--scale-noise`` → ``scale_noise``)."""
        return self.flag.lstrip("-").replace("-", "_")

    def argparse_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``ArgumentParser.add_argument`` for this option."""
        if self.flag_only:
            return {"action": "store_true", "help": self.help}
        kw: dict[str, Any] = {"default": None, "help": self.help}
        if self.choices is not None:
            kw["choices"] = self.choices
        if self.type is not None:
            kw["type"] = self.type
        if self.metavar is not None:
            kw["metavar"] = self.metavar
        return kw


def given(value: Any) -> bool:
    """Whether an option's parsed value was given on the command line: not None (an option
    left out) nor False (a flag left out). A number is given even when it is 0
    (``--fill-gaps 0`` turns gap filling off, it does not fall back to the model's)."""
    return value is not None and value is not False


@dataclass(frozen=True)
class VideoInfo:
    """What the application knows of a video when it builds a model's graph.

    Attributes
    ----------
    width, height : int
        Frame size (px).
    fps : float
        Frame rate (25 when not given).
    fps_declared : bool
        Whether the video says its frame rate (or the user gave it; by default, whether
        ``fps`` was given): a model whose ``Params.fps`` defaults to None (constants in
        seconds, converted only from a known rate) is given ``fps`` only then.
    init_box : tuple, optional
        The object's box in the first frame ``(cx, cy, w, h)`` (single-object models).
    typical_height : float, optional
        The median height of the video's detections (multi-target models), px.
    particles : int, optional
        ``--particles``: the model's particle count (per variable, or per target).
    score_range : tuple, optional
        The lowest and highest score of the video's detections (multi-target models).
    """

    width: int = 640
    height: int = 480
    fps: float | None = None
    fps_declared: bool | None = None
    init_box: tuple[float, float, float, float] | None = None
    typical_height: float | None = None
    particles: int | None = None
    score_range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.fps_declared is None:
            object.__setattr__(self, "fps_declared", self.fps is not None)
        if self.fps is None:
            object.__setattr__(self, "fps", 25.0)


#: the shared options of the toolkit's models (each model lists the ones it takes)
APPEARANCE = Option(
    "--appearance", "appearance", metavar="CUE[+CUE...]",
    help="likelihood cues per node, multiplied: colour (one colour histogram), fragments "
         "(3x3 colour fragments, median), gradient (oriented gradients), gmm (GMM-KL), rings "
         "(rotation-invariant), contrast (foreground/background colour log-odds), template "
         "(grey NCC; sees scale), cf (online correlation filter); options in parentheses, "
         "e.g. 'cf(lam=40,padding=2)+template' (default: the model's)")
SCALE_NOISE = Option(
    "--scale-noise", "scale_noise", type=finite_float("--scale-noise"),
    help="std of a shared log-scale step per frame (0: fixed size; use with a cue that sees "
         "scale; default: the model's)")
PARTS = Option("--parts", "n_parts", type=int_in("--parts", 1, 3),
               help="number of bands (2 for a person, 3 for a face; default: the model's)")


def default_build(config: ModelConfig, values: dict[str, Any], video: VideoInfo):
    """``module.build_graph(module.Params(...))`` with the options' fields and, where
    ``Params`` has them, the video's initial box, frame rate, frame size and particle
    count."""
    params_cls = config.module.Params
    declared = {f.name: f for f in dataclasses.fields(params_cls)}
    fields = set(declared)
    kwargs = {o.field: values[o.dest] for o in config.options
              if o.field is not None and given(values.get(o.dest))}
    if "init_box" in fields and video.init_box is not None:
        kwargs["init_box"] = tuple(float(v) for v in video.init_box)
    if "fps" in fields and (video.fps_declared or declared["fps"].default is not None):
        kwargs["fps"] = float(video.fps)
    if "frame_size" in fields:
        kwargs["frame_size"] = (int(video.width), int(video.height))
    if video.particles is not None and "num_particles" in fields:
        kwargs["num_particles"] = int(video.particles)
    return config.module.build_graph(params_cls(**kwargs))


@dataclass(frozen=True)
class ModelConfig:
    """A model as the application sees it.

    Attributes
    ----------
    name : str
        The model's name (``pgm track --model NAME``).
    kind : {"single-object", "multi-target", "state-space"}
    module : module
        Its ``Params`` dataclass and ``build_graph(params)``.
    summary : str
        One line for listings.
    options : tuple of Option
        Its command-line options.
    build : callable, optional
        ``build(config, values, video) -> FactorGraph`` (``values``: option ``dest`` →
        value, ``None`` when not given); default: the options' fields into ``Params``
        with the video's box, frame rate and particle count where ``Params`` has them.
    example : callable, optional
        ``example(config, values) -> (FactorGraph, note)``: a graph to draw when no video
        is at hand (``pgm graph NAME``); default: :attr:`build` on a 640×480 video with a
        box in its middle.
    """

    name: str
    kind: str
    module: Any
    summary: str
    options: tuple[Option, ...] = ()
    build: Callable[..., Any] = field(default=default_build)
    example: Callable[..., Any] | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"model {self.name!r}: kind must be one of {KINDS}, got "
                             f"{self.kind!r}")
        flags = [o.flag for o in self.options]
        if len(set(flags)) != len(flags):
            raise ValueError(f"model {self.name!r} declares an option twice: {flags}")

    def option(self, dest: str) -> Option | None:
        """The option whose argparse ``dest`` is ``dest``, if the model has it."""
        return next((o for o in self.options if o.dest == dest), None)

    def graph_for(self, values: dict[str, Any] | None = None, video: VideoInfo | None = None):
        """The model's graph for ``video`` with the options ``values``."""
        return self.build(self, dict(values or {}), video or VideoInfo())

    def example_graph(self, values: dict[str, Any] | None = None):
        """A graph to draw (``pgm graph``) and a note on what was assumed (or ``""``)."""
        if self.example is not None:
            return self.example(self, dict(values or {}))
        video = VideoInfo(init_box=(320.0, 240.0, 40.0, 100.0))
        return self.graph_for(values, video), ""
