"""Figures of clearances under load (issue 24, deliverable 6): what is drawn obeys the physics it shows.

Independent checks, read back from the drawn artists (not from the statics code):
- Newton on the platform: the joint-force arrows at each leg's platform joint, times the stated scale, sum to
  minus the external force, and their moments about the platform centre (the forces act at the R joints'
  centres) to minus the external moment;
- contact: each R joint's pin sits in its bore on the side opposite the joint's force (the bore pushes it back);
- the magnified platform, scaled back by the stated factor, is displaced by the paper's worst case
  ``dx_max`` for a push along +x (Sec. 5.2: the pushes take the clearances up to the worst case);
- a leg whose wrench intensity vanishes (pure +y push on the Aalborg 3-PPR: the y-leg's constraint force is along
  x) is drawn in light grey.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.patches import FancyArrowPatch, Polygon

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.loads import Load, loaded_pose_error
from pmaccuracy.cli import main
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.report.load_figures import UNLOADED_COLOUR, plot_load, plot_preload


def _arrows(ax) -> dict[str, tuple[complex, complex]]:
    return {p.get_gid(): tuple(complex(*xy) for xy in p._posA_posB) for p in ax.patches
            if isinstance(p, FancyArrowPatch) and p.get_gid()}


def _scale(ax) -> float:
    """N per mm of arrow, read from the legend's label."""
    labels = " ".join(ax.get_legend_handles_labels()[1])
    return float(re.search(r"1 mm of arrow = ([0-9.eE+-]+) N", labels).group(1))


@pytest.mark.parametrize("name, clear, pose, load", [
    ("aalborg_3ppr", "case2", [5.0, -3.0, np.radians(4.0)], Load(fx=7.0, fy=-3.0, m=120.0)),
    ("symmetric_3rrr", "rrr_typical", [2.0, 1.0, np.radians(-3.0)], Load(fx=-2.0, fy=6.0, m=-40.0)),
    ("symmetric_3rpr", "rpr_typical", [1.0, -2.0, np.radians(2.0)], Load(fx=1.0, m=300.0, mass=0.5)),
])
def test_drawn_forces_balance_the_load_and_pins_sit_opposite_them(name, clear, pose, load):
    robot = Manipulator.preset(name)
    fig = plot_load(robot, clear, pose, load)
    ax = fig.axes[0]
    arrows, scale = _arrows(ax), _scale(ax)
    W = load.wrench(np.asarray(pose))
    P = complex(pose[0], pose[1])
    total_f, total_m = 0j, 0.0
    for i in range(3):
        start, end = arrows[f"force {i} 2"]            # the platform joint (an R joint in every preset)
        F = (end - start) * scale
        total_f += F
        total_m += ((start - P).conjugate() * F).imag
    assert abs(total_f + complex(W[0], W[1])) <= 1e-9 * max(1.0, abs(complex(W[0], W[1])))
    assert total_m == pytest.approx(-W[2], rel=1e-9, abs=1e-9)
    start, end = arrows["external"]
    assert (end - start) * scale == pytest.approx(complex(W[0], W[1]), rel=1e-12)
    lines = {ln.get_gid(): ln for ln in ax.lines if ln.get_gid()}
    bores = {p.get_gid(): p for p in ax.patches if isinstance(p, Polygon) and (p.get_gid() or "").startswith("bore")}
    assert bores, "every preset has R clearances"
    for gid, bore in bores.items():
        _, i, k = gid.split()
        centre = complex(*bore.get_xy()[:-1].mean(axis=0))
        pin = complex(lines[f"pin {i} {k}"].get_xdata()[0], lines[f"pin {i} {k}"].get_ydata()[0])
        start, end = arrows[f"force {i} {k}"]
        assert np.angle((pin - centre) / -(end - start)) == pytest.approx(0.0, abs=1e-9)


def test_magnified_platform_is_the_worst_case_of_a_push_along_x():
    robot = Manipulator.preset("aalborg_3ppr")
    pose = np.array([10.0, 5.0, 0.0])
    fig = plot_load(robot, "case2", pose, Load(fx=10.0), magnify=100.0)
    ax = fig.axes[0]
    moved = next(p for p in ax.patches if (p.get_gid() or "").startswith("loaded platform"))
    assert moved.get_gid() == "loaded platform x 100"
    nominal = robot.platform_points(pose)
    shift = (moved.get_xy()[:3].mean(axis=0) - nominal.mean(axis=0)) / 100.0     # centroid shift / factor
    b = max_pose_errors(robot, "case2", pose[None])
    # the centroid of D_1..3 moves with the platform's rotation too: compare x of P through the exact pose
    exact = loaded_pose_error(robot, "case2", pose, Load(fx=10.0)).exact
    assert exact[0] == pytest.approx(float(b.dx_max[0]), rel=1e-3)
    centroid_arm = nominal.mean(axis=0) - pose[:2]
    expected = exact[:2] + exact[2] * np.array([-centroid_arm[1], centroid_arm[0]])
    np.testing.assert_allclose(shift, expected, rtol=0.02, atol=1e-6)


def test_an_unloaded_leg_is_grey_and_named():
    robot = Manipulator.preset("aalborg_3ppr")
    pose = np.array([0.0, 0.0, 0.0])
    fig = plot_load(robot, "case2", pose, Load(fy=10.0))
    ax = fig.axes[0]
    # the legs' polylines (more than the two points of a glyph's leader line)
    legs = [ln for ln in ax.lines if len(ln.get_xdata()) > 2]
    grey = [ln for ln in legs if ln.get_color() == UNLOADED_COLOUR]
    assert len(legs) == 3 and len(grey) == 1
    xs = np.asarray(grey[0].get_xdata(), float)
    assert np.ptp(xs) < 1e-6                       # the grey leg is the vertical one (constant x)
    assert "unloaded leg" in " ".join(ax.get_legend_handles_labels()[1])


def test_preload_figure_draws_the_designed_preload_and_flipping_legs():
    from pmaccuracy.accuracy.loads import design_preload

    robot = Manipulator.preset("aalborg_3ppr")
    pose = np.array([0.0, 0.0, 0.0])
    center, half = np.array([0.0, 0.0, 0.0]), np.array([5.0, 5.0, 100.0])
    fig = plot_preload(robot, "case2", pose, center, half)
    ax = fig.axes[0]
    arrows = _arrows(ax)
    pre = design_preload(robot, "case2", pose, center, half)
    start, end = arrows["preload"]
    labels = " ".join(ax.get_legend_handles_labels()[1])
    scale = float(re.search(r"1 mm = ([0-9.eE+-]+) N", labels).group(1))
    assert (end - start) * scale == pytest.approx(complex(pre.wrench[0], pre.wrench[1]), rel=1e-12)
    # a box symmetric about zero holds +W and -W: every leg's intensity changes sign, every leg flips
    assert "flips without preload: 1, 2, 3" in labels


def test_cli_plots_in_the_format_asked_and_checks_the_path_first(tmp_path, capsys):
    png, pdf = tmp_path / "load.png", tmp_path / "sub" / "preload.pdf"
    assert main(["load", "--pose", "0", "0", "0", "--fx", "10", "--plot", str(png), "--dpi", "60"]) == 0
    assert png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert main(["preload", "--pose", "0", "0", "0", "--fx", "-5", "5", "--plot", str(pdf)]) == 0
    assert pdf.read_bytes().startswith(b"%PDF-")
    capsys.readouterr()
    for argv, option in ((["load", "--fx", "1", "--plot", str(tmp_path / "x.doc")], "--plot"),
                         (["load", "--fx", "1", "--plot", str(tmp_path / "y.png"), "--dpi", "5"], "--dpi"),
                         (["load", "--fx", "1", "--magnify", "10"], "--magnify"),
                         (["preload", "--fx", "-1", "1", "--plot", str(tmp_path / "z.txt")], "--plot")):
        assert main([argv[0], "--pose", "0", "0", "0", *argv[1:]]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and option in err[0]
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["load.png", "preload.pdf"]


def test_plot_load_refuses_a_zero_load_and_a_bad_factor():
    from pmaccuracy.errors import ConfigError

    with pytest.raises(ConfigError, match="zero"):
        plot_load("aalborg_3ppr", "case2", [0.0, 0.0, 0.0], Load())
    for bad in (0.0, -2.0, float("nan")):
        with pytest.raises(ConfigError, match="magnify"):
            plot_load("aalborg_3ppr", "case2", [0.0, 0.0, 0.0], Load(fx=1.0), magnify=bad)


def _meshes(fig) -> dict[str, np.ndarray]:
    """Title (before any ': constant') -> the array drawn by the panel's pcolormesh."""
    out = {}
    for ax in fig.axes:
        if ax.get_title() and ax.collections:
            out[ax.get_title().split(":")[0]] = np.ma.filled(ax.collections[0].get_array(), np.nan)
    return out


def test_loaded_map_figure_draws_the_loaded_errors_of_each_pose():
    """Each panel of the map figure holds loaded_pose_error at the grid poses (computed here pose by pose)."""
    from pmaccuracy.accuracy.loads import loaded_error_map
    from pmaccuracy.report.load_figures import plot_loaded_map

    load = Load(fx=4.0, fy=-7.0, m=30.0)
    ds = loaded_error_map("symmetric_3rpr", "rpr_typical", load, [np.radians(5.0)], n=9)
    drawn = _meshes(plot_loaded_map(ds, 5.0))
    assert len(drawn) == 4                                # every leg loaded under this wrench
    xs, ys = np.meshgrid(ds["x"].values, ds["y"].values)
    inside = np.isfinite(ds["dx"].values[0])
    poses = np.column_stack([xs[inside], ys[inside], np.full(inside.sum(), np.radians(5.0))])
    ref = loaded_pose_error("symmetric_3rpr", "rpr_typical", poses, load, exact=False).first_order
    for title, column in ((r"$\delta x$ [mm]", ref[:, 0]), (r"$\delta y$ [mm]", ref[:, 1]),
                          (r"$|\delta p|$ [mm]", np.hypot(ref[:, 0], ref[:, 1])),
                          (r"$\delta\phi$ [deg]", np.degrees(ref[:, 2]))):
        Z = drawn[title].reshape(inside.shape)
        assert np.all(np.isnan(Z[~inside]))
        np.testing.assert_allclose(Z[inside], column, rtol=1e-9, atol=1e-12)


def test_wrench_set_map_figure_draws_ranges_and_flips_and_the_cli_writes_one_figure_per_orientation(tmp_path):
    from pmaccuracy.accuracy.loads import wrench_set_errors, wrench_set_map
    from pmaccuracy.report.load_figures import plot_wrench_set_map

    center, half = np.array([1.0, 0.0, 0.0]), np.array([3.0, 2.0, 40.0])
    ds = wrench_set_map("symmetric_3rpr", "rpr_typical", center, half, [0.0], n=7)
    drawn = _meshes(plot_wrench_set_map(ds, 0.0))
    xs, ys = np.meshgrid(ds["x"].values, ds["y"].values)
    inside = np.isfinite(ds["dx_lo"].values[0])
    poses = np.column_stack([xs[inside], ys[inside], np.zeros(inside.sum())])
    ref = wrench_set_errors("symmetric_3rpr", "rpr_typical", poses, center, half)
    np.testing.assert_allclose(drawn[r"$\delta x$ range [mm]"].reshape(inside.shape)[inside],
                               ref.upper[:, 0] - ref.lower[:, 0], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(drawn["legs whose contact flips"].reshape(inside.shape)[inside],
                                  ref.flips.sum(axis=1))
    png = tmp_path / "m.png"
    assert main(["load", "--map", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--fy", "-5",
                 "--grid", "7", "--phi-deg", "0", "10", "--out", str(tmp_path / "m.nc"), "--plot", str(png)]) == 0
    assert sorted(p.name for p in tmp_path.glob("m-*deg.png")) == ["m-0deg.png", "m-10deg.png"]
    assert main(["preload", "--map", "--fx", "-5", "5", "--grid", "7", "--out", str(tmp_path / "s.nc"),
                 "--plot", str(tmp_path / "s.svg")]) == 0
    assert (tmp_path / "s.svg").read_bytes().lstrip().startswith(b"<?xml")


@pytest.mark.parametrize("argv, key", [
    (["load", "--map", "--fy", "-5", "--plot", "x.png", "--magnify", "10"], "--magnify"),
    (["preload", "--fx", "-5", "5", "--disc", "0", "0", "3", "--plot", "x.png"], "--plot"),
])
def test_map_and_region_plot_options_are_checked(argv, key, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv + ["--out", "o.nc"] * ("--map" in argv)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0]
