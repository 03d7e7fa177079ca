"""Figures of a diagnosis: residual breakdown and nMSE before/after.

matplotlib is optional (``pip install sklearn-gpcd[plot]``); it is imported
inside the functions.
"""

from pathlib import Path

import numpy as np

from .._atomic import atomic_write
from ..features import REGIMES


def _pyplot():
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError(
            "plotting needs matplotlib: pip install 'sklearn-gpcd[plot]'"
        ) from exc
    return plt


def plot_residual_breakdown(breakdown, axes=None):
    """Heat map of the residual RMS by joint and regime, and RMS over time.

    Parameters
    ----------
    breakdown : ResidualBreakdown
    axes : sequence of 2 matplotlib Axes, default=None
        Created when None.

    Returns
    -------
    axes : list of Axes
    """
    plt = _pyplot()
    if axes is None:
        _, axes = plt.subplots(1, 2, figsize=(11, 3.5))
    ax = axes[0]
    grid = np.array([breakdown.regimes[r]["rms"] for r in REGIMES])
    image = ax.imshow(np.where(np.isfinite(grid), grid, np.nan), aspect="auto", cmap="magma")
    ax.set_yticks(range(len(REGIMES)), REGIMES)
    ax.set_xticks(range(breakdown.n_joints), [f"j{j + 1}" for j in range(breakdown.n_joints)])
    ax.set_title(f"nominal residual RMS [{breakdown.units}] by regime")
    plt.colorbar(image, ax=ax)
    ax = axes[1]
    for window in breakdown.time[:1]:
        for j in range(breakdown.n_joints):
            ax.plot(window["centres"], window["rms"][:, j], marker="o", label=f"j{j + 1}")
        ax.set_title(f"residual RMS over time ({window['name']})")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"RMS [{breakdown.units}]")
    ax.legend(fontsize="small", ncol=3)
    return list(axes)


def plot_nmse(before, after, ax=None, title="nMSE per joint"):
    """Bars of the per-joint nMSE before and after the diagnosis (log scale).

    Parameters
    ----------
    before, after : sequence of float
    ax : matplotlib Axes, default=None
    title : str, default="nMSE per joint"

    Returns
    -------
    ax : Axes
    """
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(5, 3.5))
    before = np.array([np.nan if b is None else b for b in before], dtype=float)
    after = np.array([np.nan if a is None else a for a in after], dtype=float)
    x = np.arange(before.size)
    ax.bar(x - 0.2, before, 0.4, label="nominal")
    ax.bar(x + 0.2, after, 0.4, label="refined")
    ax.set_yscale("log")
    ax.set_xticks(x, [f"j{j + 1}" for j in x])
    ax.set_ylabel("nMSE")
    ax.set_title(title)
    ax.legend()
    return ax


def plot_diagnosis(report, path=None):
    """One figure: residual by regime, residual over time, nMSE before/after.

    Parameters
    ----------
    report : DiagnosisReport
    path : str or Path, default=None
        Save the figure there (PNG, PDF, ... by suffix).

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.2))
    if report.breakdown is not None:
        plot_residual_breakdown(report.breakdown, axes[:2])
    where = "held-out" if report.heldout else "training"
    plot_nmse(report.nmse_before, report.nmse_after, axes[2],
              title=f"nMSE per joint ({where}, moving)")
    names = ", ".join(e["name"] for e in report.effects) or "nothing missing"
    fig.suptitle(f"Diagnosis of {report.summary.get('robot', '')}: {names}")
    fig.tight_layout()
    if path is not None:
        atomic_write(path, lambda handle: fig.savefig(handle, dpi=110,
                                                      format=Path(path).suffix[1:] or "png"))
    return fig
