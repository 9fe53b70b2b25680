"""The latent space of a learned GPDM, drawn in the style of Fig. 1 of Wang, Yin & Man (2008).

The training sequences' latent trajectories (first two latent coordinates, one line per
sequence — the model keeps the sequence boundaries in ``lengths``; a mirrored training
set holds each trajectory twice) over a greyscale image of the observation map's
predictive precision ``−ln σ²_Y(x)``: light where the model is sure of the motion it
maps a latent to, dark far from the training data.

This module takes the model by its attributes (``X``, ``lengths``, ``observe``, as
:class:`pgm.dynamics.gpdm.GPDM` has them) and imports nothing from the other layers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["plot_latent_space", "PLOT_SUFFIXES"]

#: file types :func:`plot_latent_space` writes
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def _precision_grid(model: Any, x0: np.ndarray, x1: np.ndarray, rest: np.ndarray
                    ) -> np.ndarray:
    """``−ln σ²_Y`` on the grid ``x0 × x1`` (other latent coordinates at ``rest``)."""
    g0, g1 = np.meshgrid(x0, x1)
    pts = np.empty((g0.size, 2 + rest.size))
    pts[:, 0], pts[:, 1] = g0.ravel(), g1.ravel()
    pts[:, 2:] = rest
    _, var = model.observe(pts)
    return -np.log(np.asarray(var, dtype=float)).reshape(g0.shape)


def plot_latent_space(model: Any, path: str | Path | None = None, ax: Any = None, *,
                      grid: int = 80, title: str | None = None) -> Any:
    """Draw the latent trajectories of ``model`` over its predictive precision.

    Parameters
    ----------
    model : pgm.dynamics.gpdm.GPDM
        A learned model (read: ``X``, ``lengths``, ``latent_dim``, ``observe``).
    path : str or Path, optional
        Save the figure there (``.png``, ``.svg`` or ``.pdf``).
    ax : matplotlib Axes, optional
        Draw into these axes (default: a new figure, not registered with pyplot).
    grid : int
        Grid points per axis of the background image.
    title : str, optional
        Default: ``"GPDM latent space (d = …, N = … points, S = … sequences)"``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn into.

    Notes
    -----
    With ``d > 2`` the background is the slice through the mean of the other latent
    coordinates; with ``d = 1`` the vertical axis is the frame index within a sequence
    and the background varies along ``x₁`` only.
    """
    if path is not None and Path(path).suffix.lower() not in PLOT_SUFFIXES:
        raise ValueError(f"cannot plot to {path}: use {', '.join(PLOT_SUFFIXES)}")
    grid = int(grid)
    if grid < 2:
        raise ValueError(f"grid must be at least 2, got {grid}")
    X = np.asarray(model.X, dtype=float)
    lengths = np.asarray(model.lengths, dtype=np.int64)
    n, d = X.shape
    if ax is None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(6.0, 5.0))
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    if d >= 2:
        lo, hi = X[:, :2].min(0), X[:, :2].max(0)
        pad = 0.15 * np.maximum(hi - lo, 1e-6)
        x0 = np.linspace(lo[0] - pad[0], hi[0] + pad[0], grid)
        x1 = np.linspace(lo[1] - pad[1], hi[1] + pad[1], grid)
        img = _precision_grid(model, x0, x1, X[:, 2:].mean(0))
        extent = (x0[0], x0[-1], x1[0], x1[-1])
        paths = [X[a:a + m, :2] for a, m in zip(starts, lengths, strict=True)]
        xlabel, ylabel = "$x_1$", "$x_2$"
    else:
        lo, hi = X[:, 0].min(), X[:, 0].max()
        pad = 0.15 * max(hi - lo, 1e-6)
        x0 = np.linspace(lo - pad, hi + pad, grid)
        _, var = model.observe(x0[:, None])
        t_max = max(int(lengths.max()) - 1, 1)
        img = np.tile(-np.log(np.asarray(var, dtype=float)), (2, 1))
        extent = (x0[0], x0[-1], 0.0, float(t_max))
        paths = [np.column_stack([X[a:a + m, 0], np.arange(m)])
                 for a, m in zip(starts, lengths, strict=True)]
        xlabel, ylabel = "$x_1$", "frame in sequence"
    im = ax.imshow(img, origin="lower", extent=extent, cmap="gray", aspect="auto",
                   interpolation="bilinear")
    colours = ax.figure.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    colours.set_label(r"$-\ln \sigma^2_Y(x)$ (predictive precision)")
    for k, p in enumerate(paths):
        colour = f"C{k % 10}"
        ax.plot(p[:, 0], p[:, 1], "-", color=colour, lw=0.9, alpha=0.85)
        ax.plot(p[0, 0], p[0, 1], "o", color=colour, ms=2.5)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title or f"GPDM latent space (d = {d}, N = {n} points, "
                          f"S = {lengths.size} sequences)", fontsize=10)
    if path is not None:
        fig.savefig(path, bbox_inches="tight", dpi=120)
    return fig
