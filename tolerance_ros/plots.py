"""PNG plots for the command line (matplotlib, headless). Lengths in mm, as the figures say."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def salience_bars(sens, path) -> Path:
    """Bar chart of the salience D_j per parameter (like Gao et al. Fig. 2)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(max(6.0, 0.3 * len(sens.names)), 3.6))
    ax.bar(np.arange(len(sens.names)), sens.salience * 100.0, color="tab:blue")
    ax.set_xticks(np.arange(len(sens.names)))
    ax.set_xticklabels(sens.names, rotation=90, fontsize=7)
    ax.set_ylabel(f"salience D_j [%] (lengths in {sens.length_unit})")
    ax.set_title(f"Salience of parameter errors ({sens.rows}, {sens.samples} poses)")
    fig.tight_layout()
    return _save(fig, plt, path)


def error_histogram(values_m, path, limit_m=None, title="End-effector position error", unit="mm") -> Path:
    """Histogram of position errors (like Gao et al. Fig. 6), in mm, with the design limit."""
    plt = _plt()
    scale = 1e3 if unit == "mm" else 1.0
    v = np.asarray(values_m) * scale
    fig, ax = plt.subplots(figsize=(6.0, 3.6))
    ax.hist(v, bins=60, color="tab:blue", alpha=0.85)
    if limit_m is not None:
        ax.axvline(limit_m * scale, color="tab:red", linestyle="--", label=f"limit {limit_m * scale:g} {unit}")
        ax.legend()
    ax.set_xlabel(f"|dP| [{unit}]")
    ax.set_ylabel("poses")
    ax.set_title(title)
    fig.tight_layout()
    return _save(fig, plt, path)


def line_plot(x, series: dict, path, xlabel: str, ylabel: str, title: str, logy=False) -> Path:
    """Generic line plot of named series over x."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.0, 3.6))
    for label, y in series.items():
        ax.plot(x, y, label=label)
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    return _save(fig, plt, path)


def _save(fig, plt, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
