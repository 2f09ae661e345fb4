"""Plots a person reads: every plot the commands write, on the shipped D-H arm, the shipped parallel robot
and the URDF UR10, has no text over another text or past the figure's edge and no legend over its data
(``tolerance_ros.render.layout``); and the check finds such faults where they are."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from tolerance_ros.cli import main
from tolerance_ros.render import plots
from tolerance_ros.render.layout import layout_problems

GAO = ["--robot", "gao2023_7dof"]
PUPS = ["--robot", "rong2018_3pups"]


@pytest.fixture(scope="module")
def ur10():
    from helpers import example_urdf
    return ["--robot", str(example_urdf("ur10_robot.urdf")), "--tip-link", "tool0"]


@pytest.fixture
def checked(monkeypatch):
    """{file name: layout problems} of every figure the plots module saves, checked at the dpi it is saved
    with, as it is saved."""
    found, real = {}, plots._save

    def check(fig, plt, path):
        found[Path(path).name] = layout_problems(fig, dpi=plots.DPI)
        return real(fig, plt, path)

    monkeypatch.setattr(plots, "_save", check)
    return found


def _run(*argv):
    return main([str(a) for a in argv])


def _model(robot):
    from tolerance_ros.core.models import load_robot
    return load_robot(robot[1], robot[3] if len(robot) > 2 else None)


def _budget(model, path):
    """A budget file of ``model``: 0.05 mm on lengths, 0.3 mrad on angles; its path."""
    path.write_text(yaml.safe_dump({"robot": model.name, "units": {"length": "mm", "angle": "mrad"},
                                    "tolerances": {n: 0.05 if k == "length" else 0.3
                                                   for n, k in zip(model.param_names, model.param_kinds)}}))
    return path


def _measured(model, budget, folder, poses=16, cycles=3):
    """A campaign of ``poses`` random test poses and its simulated tracker readings (10 um, 10 urad) of a
    robot built within ``budget``: (campaign path, CSV path)."""
    from tolerance_ros.core.accuracy.io import Measurements, write_csv
    from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.calibration.planning import campaign_dict
    from tolerance_ros.core.geometry import transform
    qk = model.sample_joints(poses, 5)
    campaign = folder / "campaign.yaml"
    campaign.write_text(yaml.safe_dump(campaign_dict(model, qk, "c", cycles=cycles)))
    q = np.tile(qk, (cycles, 1))
    dx = as_built_errors(load_budget(budget, model).vector_for(model), 2)
    T = measure(model, q, dx, 1e-5, 1e-5, transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2]), seed=3)
    labels = np.array([f"C{i % poses + 1}" for i in range(len(q))], dtype=object)
    meas = Measurements(np.arange(len(q)) * 1.0, T, q, model.joint_names, labels, np.arange(len(q)) // poses)
    return campaign, write_csv(folder / "m.csv", meas)


def _assert_read_well(checked, names):
    assert set(names) <= set(checked), sorted(checked)
    bad = {n: p for n, p in checked.items() if p}
    assert not bad, "\n".join(f"{n}: {p}" for n, ps in bad.items() for p in ps)


@pytest.mark.parametrize("robot", ["gao", "pups", "ur10"])
def test_sensitivity_and_verify_plots_read_well(checked, tmp_path, robot, ur10):
    argv = {"gao": GAO, "pups": PUPS, "ur10": ur10}[robot]
    budget = {"gao": "gao2023_delta2", "pups": "rong2018_table1"}.get(robot)
    budget = budget or _budget(_model(ur10), tmp_path / "b.yaml")
    assert _run("sensitivity", *argv, "--samples", 200, "--quiet", "--plot", tmp_path) == 0
    assert _run("verify", *argv, "--tolerances", budget, "--limit", "1mm", "--samples", 300, "--quiet",
                "--plot", tmp_path) in (0, 3)
    _assert_read_well(checked, ["salience.png", "verify_error_histogram.png"])


@pytest.mark.parametrize("argv", [
    [*GAO, "--solver", "ga", "--ga-tol", 40, "--ga-rounds", 2],
    [*GAO, "--solver", "ga", "--model", "optimal-precision", "--ga-tol", 40, "--ga-rounds", 2],
    ["small"]], ids=["gao-ga-rounds", "gao-ga-generations", "small-active-set"])
def test_allocate_plots_read_well(checked, tmp_path, argv):
    """The GA's two convergence plots on the paper's arm; the active-set convergence (three stacked panels)
    on a 3-DOF arm, where it takes a second rather than half a minute."""
    if argv == ["small"]:
        arm = tmp_path / "small_arm.yaml"
        arm.write_text("name: small_arm\nkind: dh\nunits: {length: mm, angle: deg}\njoints:\n"
                       "  - {name: j1, type: revolute, a: 0, alpha: 90, d: 300, theta: 0, limits: [-170, 170]}\n"
                       "  - {name: j2, type: revolute, a: 400, alpha: 0, d: 0, theta: 0, limits: [-120, 120]}\n"
                       "  - {name: j3, type: revolute, a: 300, alpha: 0, d: 0, theta: 0, limits: [-150, 150]}\n")
        argv = ["--robot", arm]
    assert _run("allocate", *argv, "--limit", "1.4mm", "--mc-poses", 300, "--quiet", "--plot", tmp_path) in (0, 3)
    _assert_read_well(checked, ["allocate_convergence.png", "allocate_error_histogram.png"])


@pytest.mark.parametrize("robot", ["gao", "ur10"])
def test_report_plan_and_calibrate_plots_read_well(checked, tmp_path, robot, ur10):
    argv = {"gao": GAO, "ur10": ur10}[robot]
    model = _model(argv)
    budget = "gao2023_delta2" if robot == "gao" else _budget(model, tmp_path / "b.yaml")
    campaign, csv_path = _measured(model, budget, tmp_path)
    assert _run("report", *argv, "--measurements", csv_path, "--budget", budget, "--campaign", campaign,
                "--out", tmp_path / "report") in (0, 3)
    assert _run("plan-campaign", *argv, "--n", 16, "--candidates", 200, "--quiet", "--plot", tmp_path) == 0
    assert _run("calibrate", *argv, "--measurements", csv_path, "--campaign", campaign, "--noise", "10um",
                "--orientation-noise", "10urad", "--folds", 3, "--quiet", "--out", tmp_path / "cal") in (0, 3)
    _assert_read_well(checked, ["error_per_pose.png", "error_vs_bound.png", "identified_vs_tolerance.png",
                                "singular_values.png", "validation.png", "parameters.png"])


def test_report_of_the_parallel_robot_and_the_paper_figures_read_well(checked, tmp_path):
    assert _run("report", *PUPS, "--measurements", "config/data/rong2018_pe_measurements.csv", "--budget",
                "rong2018_table1", "--campaign", "rong2018_pe", "--out", tmp_path / "report") == 0
    assert _run("paper", "gao2023", "--poses", 1000, "--no-synthesis", "--quiet", "--plot", tmp_path) == 0
    assert _run("paper", "rong2018", "--no-synthesis", "--quiet", "--plot", tmp_path) == 0
    _assert_read_well(checked, ["error_per_pose.png", "error_vs_bound.png", "identified_vs_tolerance.png",
                                "gao2023_fig2_salience.png", "gao2023_fig6_delta1.png", "gao2023_fig6_delta2.png",
                                "rong2018_fig3.png"])


# ---------------------------------------------------------------- the check finds what it is for


def _figure(**kw):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(4.0, 3.0), dpi=100, **kw)
    return plt, fig, ax


def test_a_legend_over_the_data_is_found():
    plt, fig, ax = _figure(layout="constrained")
    x = np.linspace(0, 1, 200)
    ax.plot(x, np.ones_like(x) * 0.95, label="flat line near the top")
    ax.plot(x, x, label="diagonal")
    ax.set_ylim(0, 1)
    ax.legend(loc="upper left")
    problems = layout_problems(fig)
    plt.close(fig)
    assert len(problems) == 1 and problems[0].startswith("axes 1 legend ['flat line near the top', 'diagonal'] "
                                                         "covers data: 'flat line near the top' in axes 1")


@pytest.mark.parametrize("artist", ["scatter", "bar", "segment"])
def test_points_bars_and_a_line_through_the_legend_are_data_it_covers(artist):
    plt, fig, ax = _figure(layout="constrained")
    if artist == "scatter":
        ax.scatter([0.1, 0.5], [0.9, 0.1], label="points")
    elif artist == "bar":
        ax.bar([0.1, 0.5], [0.95, 0.1], width=0.1, label="bars")
    else:
        ax.plot([0.0, 1.0], [0.92, 0.92], label="two vertices, neither under the legend")
        ax.set_xlim(-0.5, 1.5)
    ax.set_ylim(0, 1)
    ax.legend(loc="upper left" if artist != "segment" else "upper center")
    problems = layout_problems(fig)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
    beside = layout_problems(fig)
    plt.close(fig)
    assert len(problems) == 1 and "covers data" in problems[0], problems
    assert beside == [], beside


def test_overlapping_labels_and_a_clipped_label_are_found():
    plt, fig, ax = _figure()
    ax.plot([0, 1], [0, 1])
    ax.set_ylabel("a y label far too long to fit beside a three inch tall axes [mm]")
    ax.set_xticks([0.0, 0.02])
    ax.set_xticklabels(["first label", "second label"])
    problems = layout_problems(fig)
    plt.close(fig)
    assert "axes 1 x tick label 'first label' overlaps axes 1 x tick label 'second label'" in " ".join(problems)
    assert any(p.startswith("axes 1 y label 'a y label far too long") and "leaves the figure by" in p
               for p in problems), problems


def test_stacked_panels_with_long_y_labels_overlap_and_the_plots_module_fixes_them(tmp_path, checked):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    labels = ["largest error in the check sample / limit [-]", "cost index / its final value [-]"]
    fig, axes = plt.subplots(2, 1, figsize=(6.0, 4.0), dpi=120, sharex=True)
    for ax, label in zip(axes, labels):
        ax.plot([0, 1, 2], [300, 20, 1])
        ax.set_ylabel(label)
    fig.tight_layout()
    problems = layout_problems(fig)
    plt.close(fig)
    assert any("y label 'largest error in the check sample / limit [-]' overlaps" in p for p in problems), problems
    plots.panels_plot([0, 1, 2], [(label, {"s": [300, 20, 1]}) for label in labels], tmp_path / "p.png", "x [-]", "t")
    assert checked == {"p.png": []}


def test_a_scatter_that_fills_its_axes_keeps_the_legend_off_its_points(tmp_path, checked):
    rng = np.random.default_rng(0)
    bound = rng.uniform(0.0, 1e-3, 400)
    plots.error_vs_bound(bound, rng.uniform(0.0, 1.1e-3, 400), tmp_path / "e.png",
                         bound * 10, rng.uniform(0.0, 1.1e-2, 400))
    assert checked == {"e.png": []}


def test_texts_that_touch_by_a_pixel_are_not_an_overlap():
    plt, fig, ax = _figure()
    ax.set_axis_off()
    a = fig.text(0.1, 0.5, "left", fontsize=10)
    fig.canvas.draw()
    box = a.get_window_extent(fig.canvas.get_renderer())
    fig.text((box.x1 - 0.8) / fig.bbox.width, 0.5, "right", fontsize=10)
    touching = layout_problems(fig)
    fig.text((box.x1 - 4.0) / fig.bbox.width, 0.5, "over", fontsize=10)
    over = layout_problems(fig)
    plt.close(fig)
    assert touching == []
    assert len(over) == 2 and over[0].startswith("figure text 'left' overlaps figure text 'over'"), over


def test_a_tick_beyond_a_log_axis_view_is_not_taken_for_a_drawn_label():
    # matplotlib 3.7's log locator keeps ticks decades beyond the view; they are not drawn, and a span taken
    # in values instead of decades took them for labels below the figure
    plt, fig, ax = _figure()
    ax.semilogy([1, 2], [1e-12, 1e2])
    ax.set_yticks([1e-18, 1e-9, 1e-3, 1e1])
    ax.set_ylim(1e-13, 1e3)
    assert not [p for p in layout_problems(fig) if "10^{-18}" in p]
    plt.close(fig)


def test_per_pose_plots_read_well_at_30_poses_and_3_targets(checked, tmp_path):
    """The real sizes a campaign reaches: 30 test poses (the report's bars) and 30 poses x 3 reflectors (90 bars
    of the calibration's validation): the names are thinned or turned, never printed over one another."""
    rng = np.random.default_rng(0)
    per30 = {f"C{i + 1}": {"AP_p": v, "RP_l": v / 3} for i, v in enumerate(rng.uniform(1e-4, 1e-3, 30))}
    plots.iso_per_pose(per30, tmp_path / "error_per_pose.png")
    keys = [f"C{i + 1}@R{k + 1}" for i in range(30) for k in range(3)]
    validation = {"per_pose": {key: {"AP_p_before_m": b, "AP_p_after_m": b / 10} for key, b in
                               zip(keys, rng.uniform(1e-4, 1e-3, 90))},
                  "position_error_m": {"before": rng.uniform(1e-4, 1e-3, 270), "after": rng.uniform(1e-5, 1e-4, 270)},
                  "before": {"position_rms_m": 6e-4}, "after": {"position_rms_m": 6e-5}}
    plots.validation_before_after(validation, tmp_path / "validation.png", "30 poses x 3 targets")
    _assert_read_well(checked, ["error_per_pose.png", "validation.png"])
