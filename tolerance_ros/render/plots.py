"""PNG plots for the command line (matplotlib, headless). Lengths in mm, as the figures say. Every figure
is laid out by matplotlib's constrained layout at the dpi it is saved with, and its legends stand outside
the data (``tolerance_ros.render.layout`` checks both)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

DPI = 120


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _subplots(plt, rows, cols, size, **kw):
    """Figure of ``size`` (inches) at DPI with constrained layout, and its axes as a 2-D array."""
    return plt.subplots(rows, cols, figsize=size, dpi=DPI, layout="constrained", squeeze=False, **kw)


def _legend_beside(ax, fontsize=8):
    """The legend of ``ax`` right of its axes, top-aligned: it never covers data."""
    return ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=fontsize)


def _tick_names_height(names, fontsize=7) -> float:
    """Height (inches) that x tick labels rotated by 90 degrees need, from the longest name."""
    return 0.62 * fontsize / 72.0 * max((len(n) for n in names), default=0)


def _name_ticks(ax, names, width_in, fontsize=7):
    """x ticks named by ``names`` at 0..n-1, turned upright when they do not fit side by side, and thinned to
    every k-th name when even upright they would touch in an axes ``width_in`` inches wide."""
    names = [str(n) for n in names]
    x = np.arange(len(names))
    flat = sum(0.55 * fontsize / 72.0 * (len(n) + 1) for n in names)
    if flat <= 0.9 * width_in:
        ax.set_xticks(x)
        ax.set_xticklabels(names, fontsize=fontsize)
        return
    per_label = 1.5 * fontsize / 72.0                  # one upright label's width, with its gap
    step = max(1, int(np.ceil(len(names) * per_label / (0.9 * width_in))))
    ax.set_xticks(x[::step])
    ax.set_xticklabels(names[::step], rotation=90, fontsize=fontsize)
    if step > 1:
        ax.set_xticks(x, minor=True)


def salience_bars(sens, path) -> Path:
    """Bar chart of the salience D_j per parameter (like Gao et al. Fig. 2)."""
    plt = _plt()
    fig, ((ax,),) = _subplots(plt, 1, 1, (max(6.0, 0.3 * len(sens.names)), 2.8 + _tick_names_height(sens.names)))
    ax.bar(np.arange(len(sens.names)), sens.salience * 100.0, color="tab:blue")
    ax.set_xticks(np.arange(len(sens.names)))
    ax.set_xticklabels(sens.names, rotation=90, fontsize=7)
    ax.set_xlabel(f"kinematic parameter j (salience with lengths in {sens.length_unit})")
    ax.set_ylabel("salience D_j [%]")
    ax.set_title(f"Salience of parameter errors ({sens.rows}, {sens.samples} poses)")
    return _save(fig, plt, path)


def error_histogram(values_m, path, limit_m=None, title="End-effector position error", unit="mm") -> Path:
    """Histogram of position errors (like Gao et al. Fig. 6), in mm, with the design limit."""
    plt = _plt()
    scale = 1e3 if unit == "mm" else 1.0
    v = np.asarray(values_m) * scale
    fig, ((ax,),) = _subplots(plt, 1, 1, (7.0, 3.6))
    ax.hist(v, bins=60, color="tab:blue", alpha=0.85)
    if limit_m is not None:
        ax.axvline(limit_m * scale, color="tab:red", linestyle="--", label=f"limit {limit_m * scale:g} {unit}")
        _legend_beside(ax)
    ax.set_xlabel(f"|dP| [{unit}]")
    ax.set_ylabel("poses")
    ax.set_title(textwrap.fill(title, 70))
    return _save(fig, plt, path)


STYLES = ({"linestyle": "-"}, {"linestyle": "--", "marker": "o", "markerfacecolor": "none"},
          {"linestyle": ":", "marker": "x", "markersize": 8}, {"linestyle": "-.", "marker": "s", "markerfacecolor": "none"})


def line_plot(x, series: dict, path, xlabel: str, ylabel: str, title: str, logy=False) -> Path:
    """Named series over x on one axis; each series has its own line style and marker, so series that
    lie on top of each other stay visible."""
    return panels_plot(x, [(ylabel, series)], path, xlabel, title, logy)


def panels_plot(x, panels: list, path, xlabel: str, title: str, logy=False) -> Path:
    """Stacked panels sharing x: ``panels`` is [(y label with its unit, {series label: y})]; a panel of one
    series has no legend (its y label names it), long y labels are wrapped and aligned."""
    plt = _plt()
    fig, axes = _subplots(plt, len(panels), 1, (7.0, 1.2 + 2.0 * len(panels)), sharex=True)
    for ax, (ylabel, series) in zip(axes[:, 0], panels):
        for k, (label, y) in enumerate(series.items()):
            ax.plot(x, y, label=label, **STYLES[k % len(STYLES)])
        if logy:
            ax.set_yscale("log")
        ax.set_ylabel(textwrap.fill(ylabel, 28))
        if len(series) > 1:
            _legend_beside(ax)
    axes[-1, 0].set_xlabel(xlabel)
    axes[0, 0].set_title(title)
    fig.align_ylabels(axes[:, 0])
    return _save(fig, plt, path)


def iso_per_pose(per: dict, path) -> Path:
    """Bars of ISO 9283 AP_p and RP_l (mm) per test pose."""
    plt = _plt()
    width = min(14.0, max(7.5, 0.25 * len(per) + 3.0))
    fig, ((ax,),) = _subplots(plt, 1, 1, (width, 3.6 + _tick_names_height(per)))
    x = np.arange(len(per))
    ax.bar(x - 0.2, [v["AP_p"] * 1e3 for v in per.values()], 0.4, label="AP_p (accuracy)")
    ax.bar(x + 0.2, [v["RP_l"] * 1e3 for v in per.values()], 0.4, label="RP_l (repeatability)")
    _name_ticks(ax, list(per), width - 2.6)
    ax.set_ylabel("error [mm]")
    ax.set_title("ISO 9283 per test pose")
    _legend_beside(ax)
    return _save(fig, plt, path)


def error_vs_bound(bound_m, error_m, path, bound_rad=None, error_rad=None) -> Path:
    """Measured errors against the budget's predicted bounds: position (mm) and, when given, orientation
    (mrad) side by side; points above the diagonal exceed their bound and are drawn in red."""
    plt = _plt()
    panels = [("position", np.asarray(bound_m) * 1e3, np.asarray(error_m) * 1e3, "mm")]
    if bound_rad is not None and error_rad is not None and np.isfinite(bound_rad).any():
        panels.append(("orientation", np.asarray(bound_rad) * 1e3, np.asarray(error_rad) * 1e3, "mrad"))
    fig, axes = _subplots(plt, 1, len(panels), (6.0 * len(panels), 4.5))
    for ax, (what, b, e, unit) in zip(axes[0], panels):
        over = e > b
        ax.scatter(b[~over], e[~over], s=6, color="tab:blue", label=f"within ({int((~over).sum())})")
        ax.scatter(b[over], e[over], s=10, color="tab:red", label=f"over the bound ({int(over.sum())})")
        lim = max(float(np.nanmax(b)), float(np.nanmax(e))) * 1.05
        ax.plot([0, lim], [0, lim], "k--", label="error = bound")
        ax.set_xlabel(f"predicted {what} bound [{unit}]")
        ax.set_ylabel(f"measured {what} error [{unit}]")
        ax.set_title(f"{what.capitalize()} error vs the budget's bound")
        _legend_beside(ax)
    return _save(fig, plt, path)


def identified_vs_tolerance(names, ratio, unidentifiable, path) -> Path:
    """Bars of |identified error| / tolerance per parameter; grey where not identifiable."""
    plt = _plt()
    fig, ((ax,),) = _subplots(plt, 1, 1, (max(6.0, 0.3 * len(names)), 2.8 + _tick_names_height(names)))
    colors = ["lightgray" if u else ("tab:red" if r > 1 else "tab:blue") for r, u in zip(ratio, unidentifiable)]
    ax.bar(np.arange(len(names)), ratio, color=colors)
    ax.axhline(1.0, color="tab:red", linestyle="--")
    ax.set_xticks(np.arange(len(names)))
    ax.set_xticklabels(names, rotation=90, fontsize=7)
    ax.set_ylabel("|identified error| / tolerance")
    ax.set_title("Identified errors against tolerances (grey: not identifiable)")
    return _save(fig, plt, path)


def validation_before_after(validation: dict, path, title="Hold-out validation") -> Path:
    """Two panels from ``calibration.validate``: held-out position errors sorted (mm, log scale) and
    ISO 9283 AP_p per held-out test pose (mm, log scale), each before and after calibration."""
    plt = _plt()
    per = validation["per_pose"]
    fig, ((ax1,), (ax2,)) = _subplots(plt, 2, 1, (10.0, 6.4 + _tick_names_height(per)),
                                      gridspec_kw={"height_ratios": [1.0, 1.2]})
    errs = validation["position_error_m"]
    for label, color in (("before", "tab:red"), ("after", "tab:blue")):
        e = np.sort(np.asarray(errs[label])) * 1e3
        rms = validation[label]["position_rms_m"] * 1e3
        ax1.plot(e, (np.arange(len(e)) + 1) / len(e), color=color,
                 label=f"{label} calibration (3-D RMS {rms:.4f} mm)")
    ax1.set_xscale("log")
    ax1.set_xlabel("held-out position error |dP| [mm]")
    ax1.set_ylabel("fraction of held-out measurements")
    ax1.set_title("Held-out position errors")
    _legend_beside(ax1)
    x = np.arange(len(per))
    ax2.bar(x - 0.2, [v["AP_p_before_m"] * 1e3 for v in per.values()], 0.4, color="tab:red", label="before")
    ax2.bar(x + 0.2, [v["AP_p_after_m"] * 1e3 for v in per.values()], 0.4, color="tab:blue", label="after")
    ax2.set_yscale("log")
    _name_ticks(ax2, list(per), 7.6)
    ax2.set_xlabel("held-out test pose" + (" @ target" if any("@" in k for k in per) else ""))
    ax2.set_ylabel("ISO 9283 AP_p [mm]")
    ax2.set_title("Pose accuracy per held-out test pose")
    _legend_beside(ax2)
    fig.suptitle(textwrap.fill(title, 120), fontsize=10)
    return _save(fig, plt, path)


def identified_with_uncertainty(names, kinds, error, std, held, path) -> Path:
    """Identified parameter errors with +-3 standard uncertainties: lengths in mm, angles in mrad;
    held parameters (not identifiable, left at nominal) shown grey at 0."""
    plt = _plt()
    fig, axes = _subplots(plt, 1, 2, (max(8.0, 0.25 * len(names)), 3.2 + _tick_names_height(names, 6)))
    for ax, kind, unit in ((axes[0, 0], "length", "mm"), (axes[0, 1], "angle", "mrad")):
        sel = [j for j, k in enumerate(kinds) if k == kind]
        x = np.arange(len(sel))
        e = np.array([error[j] for j in sel]) * 1e3
        s = np.array([std[j] for j in sel]) * 1e3
        h = np.array([names[j] in held for j in sel], bool)
        ax.errorbar(x[~h], e[~h], yerr=3 * s[~h], fmt="o", color="tab:blue", ms=3, capsize=2,
                    label="identified +-3 std")
        ax.plot(x[h], e[h], "s", color="lightgray", ms=4, label="held at nominal")
        ax.axhline(0.0, color="black", linewidth=0.5)
        ax.set_xticks(x)
        ax.set_xticklabels([names[j] for j in sel], rotation=90, fontsize=6)
        ax.set_ylabel(f"identified error [{unit}]")
        ax.set_title(f"{kind} parameters")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=2, fontsize=8)
    return _save(fig, plt, path)


def singular_values(series: dict, path, title="Scaled identification Jacobian") -> Path:
    """Singular values (mm of tool displacement per expected parameter error, log scale) of named pose
    sets, largest first."""
    plt = _plt()
    from matplotlib.ticker import MaxNLocator
    fig, ((ax,),) = _subplots(plt, 1, 1, (7.5, 3.6))
    n = 0
    for label, s in series.items():
        s = np.sort(np.asarray(s, float))[::-1] * 1e3
        n = max(n, len(s))
        ax.semilogy(np.arange(1, len(s) + 1), np.maximum(s, 1e-12), marker="o", ms=3, label=label)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlim(0.5, n + 0.5)
    ax.set_xlabel("singular value index")
    ax.set_ylabel("singular value [mm per expected error]")
    ax.set_title(title)
    _legend_beside(ax)
    return _save(fig, plt, path)


def _save(fig, plt, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path
