"""Spatial synthesis certified over a region (issue 37): the scaled sources are checked against the independent
first-order model of tests/reference/spatial_error_reference.py (screw theory from the guide; it does not import
pmaccuracy), fed the reference clearance file scaled by hand: sampled densely over the region they never exceed
a target, and 5 % more than the synthesized scale exceeds the binding target at the pose the certificate says
attains it (so a larger design violates the target itself, not only the certified bound)."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref
from conftest import run_cli

import pmaccuracy as pm
import pmaccuracy.accuracy.spatial_synthesis as synthesis
from pmaccuracy.accuracy.spatial_synthesis import spatial_synthesize
from pmaccuracy.accuracy.spatial_worst import spatial_region
from pmaccuracy.errors import CertificationError, ConfigError, UnsupportedArchitectureError
from pmaccuracy.kinematics.spatial import inverse_kinematics
from pmaccuracy.model.plausibility import PlausibilityWarning
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.numerics.spatial import rotvecs

#: Target name -> (index in the reference's [dx, dy, dz, drx, dry, drz, |dp|, |dtheta|], deg -> rad factor).
INDEX = {"dx": (0, 1.0), "dy": (1, 1.0), "dz": (2, 1.0), "drx_deg": (3, np.pi / 180), "dry_deg": (4, np.pi / 180),
         "drz_deg": (5, np.pi / 180), "dp": (6, 1.0), "dtheta_deg": (7, np.pi / 180)}


def _hexapod():
    robot_dict, cl = ref.load_reference("6-UPS"), eref.load_clearances("6-UPS")
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    return robot_dict, cl, robot, SpatialErrorSources.from_dict(cl, robot, source="c.toml")


def _scaled(cl: dict, factor: float) -> dict:
    """The reference clearance file with every half-width times ``factor`` (by hand, not by the package)."""
    out = copy.deepcopy(cl)
    for leg in out["legs"]:
        for joint in leg["joints"]:
            for key in joint:
                joint[key] *= factor
    return out


def _reference(robot_dict, cl, p, R, norms: bool, n_dirs=300):
    """(8,) the reference's six exact components and (``norms``) sampled |dp|, |dtheta| (attained; NaN if not)."""
    model = eref.ErrorModel(robot_dict, cl, p, R)
    src = eref.describe(model.sources)
    M = eref.first_order_screw_theory(robot_dict, p, R, model.sources)
    out = np.full(8, np.nan)
    out[:6] = eref.component_bounds(M, src)
    if norms:
        out[6] = eref.max_norm_sampled(M, src, rows=slice(0, 3), n=n_dirs, refine=15, n_best=5)
        out[7] = eref.max_norm_sampled(M, src, rows=slice(3, 6), n=n_dirs, refine=15, n_best=5)
    return out


def _samples(robot, lo, hi, rng, n_grid, n_random):
    """Poses (x, y, z mm, roll, pitch, yaw rad) of the box [lo, hi]: a grid of the positions at the mid
    orientation and random ones; all inside the workspace (else the certificate would not cover them)."""
    axes = [np.linspace(a, b, n_grid) for a, b in zip(lo[:3], hi[:3])]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    grid = np.column_stack([grid, np.repeat(((lo[3:] + hi[3:]) / 2)[None], grid.shape[0], axis=0)])
    pts = np.vstack([grid, lo + (hi - lo) * rng.random((n_random, 6))])
    poses = np.column_stack([pts[:, :3], rotvecs(np.array([ref.rotation_rad(*a) for a in pts[:, 3:]]))])
    assert np.all(inverse_kinematics(robot, poses).within_limits)
    return pts


@pytest.mark.parametrize("targets, orientation, norms", [
    ({"dp": 0.05, "dtheta_deg": 0.02}, [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], True),
    ({"dz": 0.01, "drz_deg": 0.02, "dx": 0.05}, [[0.0, 0.0], [0.0, 0.0], [-1.5, 1.5]], False),
])
def test_dense_reference_never_exceeds_and_five_percent_more_violates(targets, orientation, norms):
    robot_dict, cl, robot, sources = _hexapod()
    o = np.radians(orientation)
    box = (-6.0, 6.0, -6.0, 6.0, 298.0, 312.0)
    region = spatial_region(robot, box=box, orientation=o)
    res = spatial_synthesize(robot, sources, targets, region=region)
    assert res.certified and res.region is region and res.scale > 0
    # the sources are the template scaled, every one of them
    for leg, leg0 in zip(res.sources.legs, sources.legs):
        for j, j0 in zip(leg, leg0):
            for (key, v), (_, v0) in zip(j.items(), j0.items()):
                assert v == pytest.approx(res.scale * v0, rel=1e-12), key
    for name, target in targets.items():
        assert res.worst[name] <= target and res.margin[name] == target - res.worst[name] >= 0
        assert res.lower[name] <= res.worst[name]
    assert res.margin[res.binding] <= 1e-12 * targets[res.binding]
    assert res.scale <= res.scale_upper <= res.scale * 1.01 * (1 + 1e-9)
    # dense sampling of the region with the reference: never above a target
    lo = np.concatenate([np.array(box)[0::2], o[:, 0]])
    hi = np.concatenate([np.array(box)[1::2], o[:, 1]])
    cl_syn = _scaled(cl, res.scale)
    rng = np.random.default_rng(7)
    pts = _samples(robot, lo, hi, rng, 4, 40)
    values = np.array([_reference(robot_dict, cl_syn, p[:3], ref.rotation_rad(*p[3:]), norms and (k < 8 or k % 4 == 0))
                       for k, p in enumerate(pts)])
    for name, target in targets.items():
        k, unit = INDEX[name]
        assert np.nanmax(values[:, k]) <= target * unit * (1 + 1e-9), name
    # 5 % more violates the binding target at the pose where the certificate attains it (reference model)
    pose = res.binding_pose
    k, unit = INDEX[res.binding]
    bigger = _reference(robot_dict, _scaled(cl, 1.05 * res.scale), pose[:3], ref.from_rotvec(pose[3:]), True, 4000)
    assert bigger[k] > targets[res.binding] * unit
    # and the attained lower values are attained: the reference at their poses (components exact)
    for name in targets:
        k, unit = INDEX[name]
        w = res.certificate[synthesis._quantity(name)]
        value = _reference(robot_dict, cl_syn, w.pose[:3], ref.from_rotvec(w.pose[3:]), k >= 6, 4000)[k] / unit
        if k < 6:
            assert value == pytest.approx(res.lower[name], rel=1e-9)
        else:
            assert res.lower[name] * (1 - 2e-3) <= value <= res.lower[name] * (1 + 1e-3)
    # the largest scale is at most scale_upper: just above it a component target fails at its attained pose
    if not norms:
        name = min(targets, key=lambda t: targets[t] / res.lower[t] * res.scale)
        k, unit = INDEX[name]
        w = res.certificate[synthesis._quantity(name)]
        over = _reference(robot_dict, _scaled(cl, res.scale_upper * (1 + 1e-6)), w.pose[:3],
                          ref.from_rotvec(w.pose[3:]), False)
        assert over[k] > targets[name] * unit


def test_budget_spent_still_meets_the_targets_and_warns():
    _, _, robot, sources = _hexapod()
    region = spatial_region(robot, box=(-6.0, 6.0, -6.0, 6.0, 298.0, 312.0), orientation=(0.0, 0.0, 0.0))
    full = spatial_synthesize(robot, sources, {"dp": 0.05}, region=region)
    with pytest.warns(PlausibilityWarning, match="not within the requested gap"):
        res = spatial_synthesize(robot, sources, {"dp": 0.05}, region=region, max_boxes=8, gap=1e-3)
    assert not res.certified and "dp" in res.uncertified and res.worst["dp"] <= 0.05
    # a looser certificate gives a smaller (safe) scale, never a larger one than the largest admissible
    assert res.scale <= full.scale_upper and res.scale_upper >= full.scale


def test_any_architecture_with_finite_upper_bounds_works_and_the_others_are_refused(monkeypatch):
    """A Delta (certified by the global worst case's affine boxes) is synthesized from its template's certificate;
    a 3-RPS over its whole workspace (sampled, not proven) is refused in one line."""
    delta = pm.load_robot("delta_clavel")
    region = spatial_region(delta, box=(-20.0, 20.0, -20.0, 20.0, -810.0, -790.0))
    base = []
    real = synthesis.spatial_global_worst

    def recorded(*args, **kw):
        base.append(real(*args, **kw))
        return base[-1]

    monkeypatch.setattr(synthesis, "spatial_global_worst", recorded)
    res = spatial_synthesize(delta, "delta_typical", {"dp": 0.05, "dz": 0.02}, region=region)
    cert = base[0]
    assert cert.certified and np.isfinite(cert["dp"].upper)
    expected = min(0.05 / cert["dp"].upper, 0.02 / cert["dz"].upper)
    assert res.scale == pytest.approx(expected, rel=1e-12)
    rps = pm.load_robot("rps_3")
    with pytest.raises((UnsupportedArchitectureError, CertificationError)) as exc:
        spatial_synthesize(rps, "rps_typical", {"dp": 0.05}, region=spatial_region(rps), max_boxes=200)
    assert "\n" not in str(exc.value)


def test_bad_arguments():
    _, _, robot, sources = _hexapod()
    region = spatial_region(robot, box=(-1.0, 1.0, -1.0, 1.0, 300.0, 302.0), orientation=(0.0, 0.0, 0.0))
    with pytest.raises(ConfigError) as exc:
        spatial_synthesize(robot, sources, {"dp": 0.05}, region=region, orientation=[0.0, 0.0, 0.1])
    assert exc.value.key == "orientation"
    with pytest.raises(ConfigError) as exc:
        spatial_synthesize(robot, sources, {"dp": 0.05}, region=(-1, 1, -1, 1, 300, 302))
    assert exc.value.key == "region"
    with pytest.raises(ConfigError, match="unknown target"):
        spatial_synthesize(robot, sources, {"dphi_deg": 0.05}, region=region)


def test_cli_certifies_over_a_box_and_refuses_in_one_line(tmp_path, capsys):
    out = tmp_path / "syn.toml"
    argv = ["synthesize", "--robot", "stewart_6ups", "--target", "dp=0.05", "--target", "dtheta_deg=0.02",
            "--box=-5,5,-5,5,395,405", "--orientation-deg", "0", "0", "0", "--out", out]
    status, text, err = run_cli([*argv, "--format", "json"], capsys)
    assert status == 0, err
    data = json.loads(text)
    assert data["certified"] and data["scale"] <= data["scale_upper"] <= 1.01 * data["scale"] * (1 + 1e-9)
    for row in data["targets"]:
        assert row["lower"] <= row["upper"] <= row["value"] and row["margin"] >= 0
    # the file bounds reads back: at the box's corners and centre no worst case exceeds the targets
    poses = [[x, y, z, 0, 0, 0] for x in (-5, 5) for y in (-5, 5) for z in (395, 405)] + [[0, 0, 400, 0, 0, 0]]
    status, text, err = run_cli(["bounds", "--robot", "stewart_6ups", "--clearances", out,
                                 *[v for p in poses for v in ("--pose", *p)], "--format", "json"], capsys)
    assert status == 0, err
    rows = json.loads(text)
    assert len(rows) == len(poses) and max(r["dp_max"] for r in rows) <= 0.05 * (1 + 1e-9)
    status, text, err = run_cli(argv[:-2], capsys)   # the table names the region and the certificate
    assert status == 0 and "certified over x in [-5, 5] mm" in text, err
    for extra, words in ((["--robot", "rps_3", "--target", "dp=0.05", "--workspace", "--max-boxes", "200"],
                          "--workspace: no certified synthesis for a 3-RPS"),
                         (["--robot", "stewart_6ups", "--target", "dp=0.05", "--gap-pct", "1"],
                          "--gap-pct: needs a region"),
                         (["--robot", "stewart_6ups", "--target", "dp=0.05", "--disc", "0", "0", "5"],
                          "--disc applies to planar robots"),
                         (["--robot", "aalborg_3ppr", "--target", "dp=0.3", "--sphere", "0", "0", "0", "5"],
                          "--sphere: is for spatial robots"),
                         (["--robot", "stewart_6ups", "--target", "dp=0.05", "--cost", tmp_path / "none.toml"],
                          "no cost preset or file")):
        status, text, err = run_cli(["synthesize", *extra], capsys)
        assert status == 2 and len(err.strip().splitlines()) == 1 and words in err, err


def test_front_door_synthesize_dispatches_a_spatial_robot():
    robot = pm.load_robot("stewart_6ups")
    region = pm.spatial_region(robot, box=(-2.0, 2.0, -2.0, 2.0, 398.0, 402.0), orientation=(0.0, 0.0, 0.0))
    res = pm.synthesize(robot, region, ["dp=0.05", "dz=0.01"], clearances="ups_typical")
    direct = spatial_synthesize(robot, "ups_typical", {"dp": 0.05, "dz": 0.01}, region=region)
    assert isinstance(res, pm.SpatialSynthesis) and res.scale == direct.scale and res.certified
    for kw, key in (({"mode": "cheapest"}, "mode"), ({"costs": [1.0]}, "costs")):
        with pytest.raises(ConfigError) as exc:
            pm.synthesize(robot, region, {"dp": 0.05}, **kw)
        assert exc.value.key == key
    with pytest.raises(ConfigError, match="SpatialRegion"):
        pm.synthesize(robot, pm.make_region(pm.load_robot("aalborg_3ppr"), (0.0, 0.0), None), {"dp": 0.05})


def _by_factor(cl: dict, factors: dict) -> dict:
    """The reference clearance file with each source times its factor (``legs[i].joints[j].key`` labels)."""
    out = copy.deepcopy(cl)
    for i, leg in enumerate(out["legs"]):
        for j, joint in enumerate(leg["joints"]):
            for key in joint:
                joint[key] *= factors[f"legs[{i + 1}].joints[{j + 1}].{key}"]
    return out


def test_min_cost_meets_the_targets_densely_and_costs_less_than_uniform(tmp_path):
    pytest.importorskip("cvxpy")
    robot_dict, cl, robot, sources = _hexapod()
    box = (-6.0, 6.0, -6.0, 6.0, 298.0, 312.0)
    region = spatial_region(robot, box=box, orientation=(0.0, 0.0, 0.0))
    targets = {"dp": 0.05, "dtheta_deg": 0.02}
    with pytest.warns(PlausibilityWarning, match="no first-order effect") as caught:
        res = spatial_synthesize(robot, sources, targets, region=region, mode="min-cost", n=5)
    uniform = spatial_synthesize(robot, sources, targets, region=region)
    assert res.mode == "min-cost" and res.scale is None and all(res.worst[k] <= v for k, v in targets.items())
    # a 6-UPS leg's sources act through its length only: rotations about the base joint (tilt, direction), the
    # slide's lateral play and tilt do not move the platform (guide, spatial errors); they are kept, as said
    kept = str(caught[0].message).split(": no first-order")[0].split(", ")
    assert {label.rsplit(".", 1)[1] for label in kept} == {"tilt", "direction", "lateral"}
    # the uniform design is feasible: the optimum costs no more (same sources, the moving ones; 1 % certificates)
    moving = [label for label in res.factors if label not in kept]
    assert res.cost <= len(moving) / uniform.scale * 1.02
    assert res.cost == pytest.approx(sum(1.0 / res.factors[label] for label in moving), rel=1e-9)
    # dense sampling with the reference (clearances scaled source by source by hand): never above a target
    cl_syn = _by_factor(cl, res.factors)
    lo = np.array([box[0], box[2], box[4], 0.0, 0.0, 0.0])
    hi = np.array([box[1], box[3], box[5], 0.0, 0.0, 0.0])
    pts = _samples(robot, lo, hi, np.random.default_rng(8), 3, 9)
    values = np.array([_reference(robot_dict, cl_syn, p[:3], np.eye(3), True) for p in pts])
    assert np.max(values[:, 6]) <= 0.05 * (1 + 1e-9) and np.max(values[:, 7]) <= np.radians(0.02)
    # 5 % more of every source exceeds the binding target at the certificate's attained pose
    pose = res.binding_pose
    bigger = _reference(robot_dict, _by_factor(cl, {k: 1.05 * v for k, v in res.factors.items()}), pose[:3],
                        ref.from_rotvec(pose[3:]), True, 4000)
    k, unit = INDEX[res.binding]
    assert bigger[k] > targets[res.binding] * unit
    # a source weighing 4 times more is given more room (the optimum's factor grows with its weight)
    label = "legs[1].joints[1].radial"
    costs = tmp_path / "costs.toml"
    costs.write_text("[[legs]]\njoints = [{radial = 4.0}]\n", encoding="utf-8")
    with pytest.warns(PlausibilityWarning):
        heavy = spatial_synthesize(robot, sources, targets, region=region, mode="min-cost", n=5, costs=costs)
    assert heavy.factors[label] > 1.2 * res.factors[label]
    assert all(heavy.worst[k] <= v for k, v in targets.items())


def test_min_cost_on_the_grid_is_exact_there_and_bad_costs_are_refused(tmp_path):
    pytest.importorskip("cvxpy")
    robot = pm.load_robot("upu_3")
    template = pm.load_clearances("upu_typical", robot)
    with pytest.warns(PlausibilityWarning, match="lateral"):   # a 3-UPU slide's lateral play: no effect
        res = spatial_synthesize(robot, template, {"dp": 0.1, "dz": 0.02}, mode="min-cost", n=6)
    ds = pm.spatial_error_map(robot, res.sources, n=6)
    assert float(np.nanmax(ds.dp_max.values)) <= 0.1 * (1 + 1e-9)
    assert float(np.nanmax(ds.dz_max.values)) <= 0.02 * (1 + 1e-9)
    assert max(float(np.nanmax(ds.dp_max.values)) / 0.1, float(np.nanmax(ds.dz_max.values)) / 0.02) \
        == pytest.approx(1.0, rel=1e-9)
    for text, key in (("[[legs]]\njoints = [{radial = -1.0}]\n", "legs[1].joints[1].radial"),
                      ("[[legs]]\njoints = [{}, {}, {}, {}]\n", "legs[1].joints"),
                      ("[[legs]]\njoints = [{nope = 1.0}]\n", "legs[1].joints[1].nope")):
        path = tmp_path / "c.toml"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(ConfigError) as exc:
            spatial_synthesize(robot, template, {"dp": 0.1}, mode="min-cost", n=6, costs=path)
        assert exc.value.key == key, exc.value
    with pytest.raises(ConfigError) as exc:
        spatial_synthesize(robot, template, {"dp": 0.1}, costs=[1.0])
    assert exc.value.key == "costs"


def test_cli_min_cost_over_a_box(tmp_path, capsys):
    pytest.importorskip("cvxpy")
    costs = tmp_path / "costs.toml"
    costs.write_text("[[legs]]\njoints = [{radial = 4.0}]\n", encoding="utf-8")
    status, text, err = run_cli(["synthesize", "--robot", "stewart_6ups", "--target", "dp=0.05", "--cost", costs,
                                 "--box=-3,3,-3,3,397,403", "--orientation-deg", "0", "0", "0", "--format", "json"],
                                capsys)
    assert status == 0, err
    data = json.loads(text)
    assert data["mode"] == "min-cost" and data["targets"][0]["upper"] <= 0.05 and data["certified"]
    moving = {k: v for k, v in data["factors"].items() if not k.endswith(("tilt", "direction", "lateral"))}
    assert data["cost"] == pytest.approx(sum((4.0 if k == "legs[1].joints[1].radial" else 1.0) / v
                                             for k, v in moving.items()), rel=1e-9)
