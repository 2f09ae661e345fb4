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
    ax.set_xlabel("kinematic parameter j")
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


STYLES = ({"linestyle": "-"}, {"linestyle": "--", "marker": "o", "markerfacecolor": "none"},
          {"linestyle": ":", "marker": "x", "markersize": 8}, {"linestyle": "-.", "marker": "s", "markerfacecolor": "none"})


def line_plot(x, series: dict, path, xlabel: str, ylabel: str, title: str, logy=False) -> Path:
    """Named series over x on one axis; each series has its own line style and marker, so series that
    lie on top of each other stay visible."""
    return panels_plot(x, [(ylabel, series)], path, xlabel, title, logy)


def panels_plot(x, panels: list, path, xlabel: str, title: str, logy=False) -> Path:
    """Stacked panels sharing x: ``panels`` is [(y label with its unit, {series label: y})]."""
    plt = _plt()
    fig, axes = plt.subplots(len(panels), 1, figsize=(6.0, 2.2 + 2.0 * len(panels)), sharex=True, squeeze=False)
    for ax, (ylabel, series) in zip(axes[:, 0], panels):
        for k, (label, y) in enumerate(series.items()):
            ax.plot(x, y, label=label, **STYLES[k % len(STYLES)])
        if logy:
            ax.set_yscale("log")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=8)
    axes[-1, 0].set_xlabel(xlabel)
    axes[0, 0].set_title(title)
    fig.tight_layout()
    return _save(fig, plt, path)


def iso_per_pose(per: dict, path) -> Path:
    """Bars of ISO 9283 AP_p and RP_l (mm) per test pose."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.6))
    x = np.arange(len(per))
    ax.bar(x - 0.2, [v["AP_p"] * 1e3 for v in per.values()], 0.4, label="AP_p (accuracy)")
    ax.bar(x + 0.2, [v["RP_l"] * 1e3 for v in per.values()], 0.4, label="RP_l (repeatability)")
    ax.set_xticks(x)
    ax.set_xticklabels(list(per))
    ax.set_ylabel("mm")
    ax.set_title("ISO 9283 per test pose")
    ax.legend()
    fig.tight_layout()
    return _save(fig, plt, path)


def error_vs_bound(bound_m, error_m, path, bound_rad=None, error_rad=None) -> Path:
    """Measured errors against the budget's predicted bounds: position (mm) and, when given, orientation
    (mrad) side by side; points above the diagonal exceed their bound and are drawn in red."""
    plt = _plt()
    panels = [("position", np.asarray(bound_m) * 1e3, np.asarray(error_m) * 1e3, "mm")]
    if bound_rad is not None and error_rad is not None and np.isfinite(bound_rad).any():
        panels.append(("orientation", np.asarray(bound_rad) * 1e3, np.asarray(error_rad) * 1e3, "mrad"))
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4.5), squeeze=False)
    for ax, (what, b, e, unit) in zip(axes[0], panels):
        over = e > b
        ax.scatter(b[~over], e[~over], s=6, color="tab:blue", label=f"within ({int((~over).sum())})")
        ax.scatter(b[over], e[over], s=10, color="tab:red", label=f"over the bound ({int(over.sum())})")
        lim = max(float(np.nanmax(b)), float(np.nanmax(e))) * 1.05
        ax.plot([0, lim], [0, lim], "k--", label="error = bound")
        ax.set_xlabel(f"predicted {what} bound [{unit}]")
        ax.set_ylabel(f"measured {what} error [{unit}]")
        ax.set_title(f"{what.capitalize()} error vs the budget's bound")
        ax.legend()
    fig.tight_layout()
    return _save(fig, plt, path)


def identified_vs_tolerance(names, ratio, unidentifiable, path) -> Path:
    """Bars of |identified error| / tolerance per parameter; grey where not identifiable."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(max(6, 0.3 * len(names)), 3.6))
    colors = ["lightgray" if u else ("tab:red" if r > 1 else "tab:blue") for r, u in zip(ratio, unidentifiable)]
    ax.bar(np.arange(len(names)), ratio, color=colors)
    ax.axhline(1.0, color="tab:red", linestyle="--")
    ax.set_xticks(np.arange(len(names)))
    ax.set_xticklabels(names, rotation=90, fontsize=7)
    ax.set_ylabel("|identified error| / tolerance")
    ax.set_title("Identified errors against tolerances (grey: not identifiable)")
    fig.tight_layout()
    return _save(fig, plt, path)


def _save(fig, plt, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
