"""Regions of any shape: discs and polygons against independent references.

References: point-in-polygon by matplotlib's ``Path.contains_points`` (a separate
implementation), box classification by dense sampling of each box, and the
certified worst case over a disc or polygon by brute force: :func:`max_pose_errors`
at dense polar / grid and random positions inside the shape that
:func:`inverse_kinematics` puts in the joint ranges.
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.global_worst import global_worst, largest_disc, make_region
from pmaccuracy.accuracy.regions import INSIDE, OUTSIDE, Disc, Polygon, Rect, load_polygon
from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError
from pmaccuracy.io.resolve import load_clearances
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.model.manipulator import Manipulator

AALBORG = Manipulator.preset("aalborg_3ppr")
CASE1 = load_clearances("case1", AALBORG)
RNG = np.random.default_rng(25)
PENTAGON = ((-12.0, -20.0), (18.0, -16.0), (22.0, 4.0), (2.0, 12.0), (-6.0, -4.0))   # not convex at (-6, -4)


def in_disc_points(cx, cy, r, n_r=40, n_t=160, n_random=4000):
    rr, tt = np.meshgrid(np.linspace(0, r, n_r), np.linspace(0, 2 * np.pi, n_t, endpoint=False))
    u = np.sqrt(RNG.uniform(size=n_random)) * r
    v = RNG.uniform(0, 2 * np.pi, n_random)
    rad = np.concatenate([rr.ravel(), u])
    ang = np.concatenate([tt.ravel(), v])
    return np.column_stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)])


def brute_max(points_xy, phis):
    """Largest exact maxima (dx, dy, dphi, dp) over the positions at the orientations, in the workspace."""
    pts = np.vstack([np.column_stack([points_xy, np.full(len(points_xy), p)]) for p in phis])
    pts = pts[inverse_kinematics(AALBORG, pts).within_limits]
    b = max_pose_errors(AALBORG, CASE1, pts, singular="nan", max_condition=np.inf)
    return np.nanmax(np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max]), axis=0)


def test_polygon_contains_matches_matplotlib():
    poly = Polygon(PENTAGON)
    xy = RNG.uniform(-30, 30, size=(5000, 2))
    ref = MplPath(np.array(PENTAGON + (PENTAGON[0],)), closed=True).contains_points(xy)
    assert np.array_equal(poly.contains(xy[:, 0], xy[:, 1]), ref)


@pytest.mark.parametrize("shape", [Disc((3.0, -2.0), 11.0), Polygon(PENTAGON), Rect((-5.0, 8.0), (-9.0, 2.0))])
def test_box_classification_is_sound(shape):
    lo = RNG.uniform(-30, 25, size=(400, 2))
    size = RNG.uniform(0.1, 12, size=(400, 2))
    boxes = np.column_stack([lo[:, 0], lo[:, 0] + size[:, 0], lo[:, 1], lo[:, 1] + size[:, 1]])
    cls = shape.classify(boxes)
    t = np.linspace(0, 1, 15)
    for b, c in zip(boxes, cls):
        X, Y = np.meshgrid(b[0] + t * (b[1] - b[0]), b[2] + t * (b[3] - b[2]))
        inside = shape.contains(X, Y)
        if c == INSIDE:
            assert inside.all()
        elif c == OUTSIDE:
            assert not inside.any()
    assert (cls == INSIDE).any() and (cls == OUTSIDE).any() and (cls == 0).any()


def test_nearest_points_are_in_the_shape():
    for shape in (Disc((3.0, -2.0), 11.0), Polygon(PENTAGON)):
        xy = RNG.uniform(-40, 40, size=(500, 2))
        q = shape.nearest(xy[:, 0], xy[:, 1])
        assert shape.contains(q[:, 0], q[:, 1]).all()
        b = shape.boundary(50)
        assert shape.contains(b[:, 0], b[:, 1]).all()


@pytest.mark.parametrize("make, needle", [
    (lambda: Disc((0, 0), -1.0), "radius must be > 0"),
    (lambda: Disc((0, 0), 0.0), "radius must be > 0"),
    (lambda: Polygon(((0, 0), (1, 1))), "at least 3 vertices"),
    (lambda: Polygon(((0, 0), (10, 10), (10, 0), (0, 10))), "intersects itself"),
    (lambda: Polygon(((0, 0), (1, 1), (2, 2))), "zero area"),
    (lambda: Polygon(((0, 0), (1, np.nan), (2, 0))), "finite"),
])
def test_bad_shapes(make, needle):
    with pytest.raises(ConfigError, match=needle):
        make()


def test_polygon_files(tmp_path):
    (tmp_path / "p.csv").write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in PENTAGON) + "\n")
    (tmp_path / "p.toml").write_text("vertices = [" + ", ".join(f"[{x}, {y}]" for x, y in PENTAGON) + "]\n")
    assert load_polygon(tmp_path / "p.csv") == Polygon(PENTAGON) == load_polygon(tmp_path / "p.toml")
    (tmp_path / "bad.csv").write_text("x,y\n0,0\n1,a\n2,0\n")
    with pytest.raises(ConfigError, match="line 3"):
        load_polygon(tmp_path / "bad.csv")


@pytest.mark.parametrize("phi", [(0.0, 0.0), pytest.param((np.radians(-2), np.radians(2)), marks=pytest.mark.slow)])
def test_disc_certified_against_brute_force_and_inside_its_box(phi):
    disc = Disc((5.0, -5.0), 15.0)
    res = global_worst(AALBORG, CASE1, make_region(AALBORG, phi, disc))
    phis = np.linspace(*phi, 1 if phi[0] == phi[1] else 5)
    ref = brute_max(in_disc_points(5.0, -5.0, 15.0), phis)
    box = global_worst(AALBORG, CASE1, make_region(AALBORG, phi, disc.bounds))
    for i, (q, w) in enumerate(res.quantities.items()):
        assert w.converged
        assert w.upper >= ref[i] * (1 - 1e-12), q                 # never below a sample of the disc
        assert w.lower <= ref[i] * (1 + 2e-3), q                  # the brute force gets within a small gap
        assert np.hypot(w.pose[0] - 5.0, w.pose[1] + 5.0) <= 15.0, q    # the worst pose is in the disc
        assert phi[0] <= w.pose[2] <= phi[1]
        b = max_pose_errors(AALBORG, CASE1, w.pose[None])
        assert [b.dx_max, b.dy_max, b.dphi_max, b.dp_max][i][0] == pytest.approx(w.lower, rel=1e-12)
        assert w.lower <= box[q].upper                               # disc worst <= bounding box worst
    # the bounding square's worst dp lies outside the disc, and is larger than the disc's
    assert not disc.contains(*box["dp"].pose[:2])
    assert box["dp"].lower > res["dp"].upper


def test_polygon_certified_against_brute_force():
    poly = Polygon(PENTAGON)
    res = global_worst(AALBORG, CASE1, make_region(AALBORG, (0.0, 0.0), poly))
    X, Y = np.meshgrid(np.linspace(-12, 22, 241), np.linspace(-20, 12, 241))
    xy = np.column_stack([X.ravel(), Y.ravel()])
    xy = np.vstack([xy, RNG.uniform([-12, -20], [22, 12], size=(4000, 2))])
    xy = xy[MplPath(np.array(PENTAGON + (PENTAGON[0],)), closed=True).contains_points(xy, radius=1e-9)]
    ref = brute_max(np.vstack([xy, np.array(PENTAGON)]), [0.0])
    for i, (q, w) in enumerate(res.quantities.items()):
        assert w.converged
        assert w.upper >= ref[i] * (1 - 1e-12), q
        assert w.lower <= ref[i] * (1 + 2e-3), q
        assert poly.contains(*w.pose[:2]), q
    box = global_worst(AALBORG, CASE1, make_region(AALBORG, (0.0, 0.0), poly.bounds))
    for q, w in res.quantities.items():
        assert w.lower <= box[q].upper, q                            # polygon worst <= bounding box worst


def test_largest_disc_against_brute_force():
    target = 0.24
    res = largest_disc(AALBORG, CASE1, (0.0, 0.0), (0.0, 0.0), {"dp": target}, tol=0.5)
    assert 0 < res.radius_lower < res.radius_upper <= res.radius_lower + 1.0   # tol + the undecided band
    inner = brute_max(in_disc_points(0.0, 0.0, res.radius_lower), [0.0])
    assert inner[3] <= target                                   # holds inside the certified radius
    outer = brute_max(in_disc_points(0.0, 0.0, res.radius_upper + 0.05), [0.0])
    assert outer[3] > target                                     # fails just outside the upper end
    assert res.holds["dp"].upper <= target < res.fails["dp"].lower


def test_cli_disc_and_polygon(capsys, tmp_path):
    import json

    assert main(["worst", "--phi-deg", "0", "0", "--disc", "5", "-5", "15", "--grid", "21", "1",
                 "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["region"].startswith("the disc of centre (5, -5) mm and radius 15 mm")
    for r in data["quantities"]:
        assert np.hypot(r["x"] - 5, r["y"] + 5) <= 15
    (tmp_path / "p.csv").write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in PENTAGON) + "\n")
    assert main(["worst", "--phi-deg", "0", "0", "--polygon", str(tmp_path / "p.csv"), "--grid", "21", "1",
                 "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert all(Polygon(PENTAGON).contains(r["x"], r["y"]) for r in data["quantities"])


@pytest.mark.parametrize("argv, needle", [
    (["--disc", "0", "0", "-3"], "--disc: the disc's radius must be > 0"),
    (["--polygon", "0,0,1,1"], "--polygon: a polygon needs at least 3 vertices"),
    (["--polygon=0,0,10,10,10,0,0,10"], "--polygon: the polygon intersects itself"),
    (["--polygon", "missing.csv"], "no such file"),
    (["--disc", "300", "300", "5"], "--disc:"),
    (["--box=-10,10,5"], "--box: expected x0,x1,y0,y1"),
    (["--largest-disc", "0", "0"], "--largest-disc: give at least one --target"),
    (["--largest-disc", "300", "0", "--target", "dp=0.2"], "--largest-disc: the centre"),
])
def test_cli_bad_regions_exit_2_with_one_line(capsys, argv, needle):
    assert main(["worst", "--phi-deg", "0", "0", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err


def test_error_map_over_a_disc_is_nan_outside_and_exact_inside():
    from pmaccuracy.accuracy.maps import error_map

    ds = error_map(AALBORG, CASE1, 0.0, 31, region=Disc((5.0, -5.0), 15.0))
    assert "disc of centre (5, -5)" in ds.attrs["region"]
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    in_disc = np.hypot(X - 5.0, Y + 5.0) <= 15.0
    finite = np.isfinite(ds["dp_max"].values[0])
    assert not finite[~in_disc].any()
    assert finite.sum() > 0.7 * in_disc.sum()
    b = max_pose_errors(AALBORG, CASE1, np.column_stack([X[finite], Y[finite], np.zeros(finite.sum())]))
    np.testing.assert_allclose(ds["dp_max"].values[0][finite], b.dp_max, rtol=1e-12)
    # the map's largest value never exceeds the certified worst case over the disc
    res = global_worst(AALBORG, CASE1, make_region(AALBORG, (0.0, 0.0), Disc((5.0, -5.0), 15.0)))
    assert float(ds["dp_max"].max()) <= res["dp"].upper


def test_region_statistics_over_a_polygon():
    from pmaccuracy.accuracy.distributions import region_statistics

    ds = region_statistics(AALBORG, CASE1, [0.0], 15, samples=200, region=Polygon(PENTAGON))
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    ref = MplPath(np.array(PENTAGON + (PENTAGON[0],)), closed=True).contains_points(
        np.column_stack([X.ravel(), Y.ravel()]), radius=1e-9).reshape(X.shape)
    finite = np.isfinite(ds["dp_std"].values[0])
    assert not finite[~ref].any() and finite.any()
    assert "polygon" in ds.attrs["region"]


def test_synthesis_over_a_disc_holds_by_brute_force_and_allows_more_than_its_box():
    from pmaccuracy.accuracy.synthesis import synthesize

    disc = Disc((5.0, -5.0), 15.0)
    res = synthesize(AALBORG, make_region(AALBORG, (0.0, 0.0), disc), {"dp": 0.2}, template="case1")
    box = synthesize(AALBORG, make_region(AALBORG, (0.0, 0.0), disc.bounds), {"dp": 0.2}, template="case1")
    assert res.scale > box.scale
    pts = in_disc_points(5.0, -5.0, 15.0)
    pts = np.column_stack([pts, np.zeros(len(pts))])
    pts = pts[inverse_kinematics(AALBORG, pts).within_limits]
    b = max_pose_errors(AALBORG, res.clearances, pts)
    assert b.dp_max.max() <= 0.2 * (1 + 1e-9)
    assert b.dp_max.max() >= 0.2 * (1 - 2e-3)          # and the disc's worst pose is close to the target


@pytest.mark.parametrize("argv, needle", [
    (["map", "--phi-deg", "0", "--out", "OUT/m.zarr", "--disc", "0", "0", "5"], "--disc: a region applies"),
    (["map", "--phi-deg", "0", "--out", "OUT/m.nc", "--polygon", "0,0,1"], "--polygon: an odd number"),
    (["statistics", "--pose", "0", "0", "0", "--disc", "0", "0", "4"], "--disc: a region goes with a map"),
    (["synthesize", "--target", "dp=0.2", "--disc", "0", "0", "0"], "--disc: the disc's radius must be > 0"),
    (["synthesize", "--target", "dp=0.2", "--disc", "300", "0", "4"], "--disc: the disc of centre (300, 0)"),
    (["statistics", "--phi-deg", "0", "--out", "OUT/m.nc", "--disc", "300", "0", "4"], "--disc: the disc of centre"),
])
def test_cli_regions_on_other_commands_exit_2(capsys, tmp_path, argv, needle):
    argv = [a.replace("OUT", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err
    assert not (tmp_path / "m.nc").exists()
