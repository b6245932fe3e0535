"""Matplotlib figures without pyplot, and their PNG files.

A figure made here is a plain :class:`matplotlib.figure.Figure`: no backend is chosen, no figure is registered
with pyplot and nothing process-wide changes; :meth:`Figure.savefig` renders a PNG with Agg by itself, and the
figure is freed with its last reference. Matplotlib is imported when the first figure is made, not when this
module is.
"""

from __future__ import annotations

from pathlib import Path

from camsim.io.atomic import atomic_path

__all__ = ["DPI", "new_figure", "save_png"]

DPI = 110
"""Resolution of every PNG figure camsim writes. Unit: dots per inch."""


def new_figure(**figure_kwargs):
    """A new figure, outside pyplot.

    Parameters
    ----------
    **figure_kwargs
        Passed to :class:`matplotlib.figure.Figure` (``figsize`` in inches, ``layout``, ...).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    return Figure(**figure_kwargs)


def save_png(fig, path: str | Path, *, dpi: float = DPI, **savefig_kwargs) -> Path:
    """Write ``fig`` as a PNG file at ``path``, atomically (see :func:`camsim.io.atomic.atomic_path`).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or pathlib.Path
        Destination; its folder must exist.
    dpi : float
        Resolution. Unit: dots per inch.
    **savefig_kwargs
        Passed to :meth:`matplotlib.figure.Figure.savefig` (e.g. ``bbox_inches="tight"``).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, **savefig_kwargs)
    return path
