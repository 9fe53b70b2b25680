"""Variables of a factor graph.

A :class:`Variable` is a *template*: it exists once per frame and the engine unrolls
time. Its ``role`` tells the engine which belief represents it:

========== ================================================================
role       meaning
========== ================================================================
``part``   an image region of an object (a box ``(cx, cy, w, h)``, ...)
``state``  a generic state vector (position, velocity, ...)
``latent`` a latent coordinate (e.g. a GPDM latent point)
``noise``  a noise parameter with an exponential-family belief (VB)
``set``    a random finite set whose belief is an intensity (PHD)
========== ================================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Variable", "ROLES"]

ROLES = ("part", "state", "latent", "noise", "set")


@dataclass(frozen=True)
class Variable:
    """A variable template of a factor graph.

    Parameters
    ----------
    name : str
        Unique name within the graph.
    dim : int
        Dimension of one value (a particle of this variable has shape ``(dim,)``).
    role : str
        One of :data:`ROLES`.
    labels : tuple of str, optional
        Names of the components, e.g. ``("cx", "cy", "w", "h")``; used for drawing,
        for building matrices from named indices and in saved declarations.
    """

    name: str
    dim: int
    role: str = "state"
    labels: tuple[str, ...] | None = field(default=None)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"variable name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.dim, int) or isinstance(self.dim, bool) or self.dim < 1:
            raise ValueError(f"variable {self.name!r}: dim must be a positive int, got {self.dim!r}")
        if self.role not in ROLES:
            raise ValueError(
                f"variable {self.name!r}: unknown role {self.role!r} (expected one of {ROLES})")
        if self.labels is not None:
            labels = tuple(str(s) for s in self.labels)
            object.__setattr__(self, "labels", labels)
            if len(labels) != self.dim:
                raise ValueError(f"variable {self.name!r}: {len(labels)} labels for dim {self.dim}")

    def index(self, label: str) -> int:
        """Position of the component called ``label``."""
        if self.labels is None or label not in self.labels:
            raise ValueError(f"variable {self.name!r} has no component {label!r}")
        return self.labels.index(label)

    def to_dict(self) -> dict:
        """JSON-ready description."""
        d = {"name": self.name, "dim": self.dim, "role": self.role}
        if self.labels is not None:
            d["labels"] = list(self.labels)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Variable:
        """Inverse of :meth:`to_dict`."""
        if not isinstance(d, dict):
            raise ValueError(f"malformed variable declaration {d!r}: expected an object with "
                             f"'name' and 'dim'")
        labels = d.get("labels")
        dim = d["dim"]
        if isinstance(dim, bool) or not isinstance(dim, (int, float)) or int(dim) != dim:
            raise ValueError(f"variable {d.get('name')!r}: dim must be an integer, got {dim!r}")
        return cls(name=d["name"], dim=int(dim), role=d.get("role", "state"),
                   labels=tuple(labels) if labels is not None else None)
