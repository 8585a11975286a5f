"""One engine: the paper's 3-PPR link-parameter tolerances (Eq. 9-10) as per-joint sources, and the polar keys.

Independent references:
- the paper's Appendix A diagonals ``H_q`` (``error_model.H_diagonals``, itself checked against finite
  differences in ``test_error_model.py``): ``dzeta_max = sum_i |A^-1[row, i]| sum_q t_q,i |H_q,i|``;
- central finite differences of the exact model: the robot file's parameter changed (``Manipulator.perturbed``
  for a 3-PPR, the base / platform points moved in a 3-RPR file), forward kinematics at the nominal
  actuator values.
"""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.certified import certified_pose_errors
from pmaccuracy.accuracy.distributions import pose_statistics
from pmaccuracy.accuracy.error_model import H_diagonals, LINK_VARIATIONS, pose_error, pose_state
from pmaccuracy.accuracy.global_worst import as_sources
from pmaccuracy.errors import ClearanceError
from pmaccuracy.kinematics import forward_kinematics, inverse_kinematics
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.model.sources import (FIRST_ORDER_ONLY, ErrorSources, JointErrors, first_order_error,
                                      polar_coefficient, worst_configuration)

ANGLES = {"alpha", "beta", "gamma", "theta", "psi"}
POSES = np.array([[0.0, 0.0, 0.0], [12.0, -8.0, np.radians(7.0)], [-15.0, 10.0, np.radians(-12.0)],
                  [5.0, 20.0, np.radians(3.0)]])


def paper_bounds(robot: Manipulator, poses: np.ndarray, tol: dict[str, np.ndarray]) -> np.ndarray:
    """(n, 3) dx, dy, dphi maxima from the paper's diagonals H_q (Appendix A) and A^-1 (Eq. 11)."""
    st = pose_state(robot, poses)
    H = H_diagonals(robot, st)
    c = sum(t * np.abs(H[q]) for q, t in tol.items())
    return np.einsum("nij,nj->ni", np.abs(st.A_inv), c)


@pytest.mark.parametrize("robot_name", ["aalborg_3ppr", "symmetric_3ppr"])
@pytest.mark.parametrize("q", LINK_VARIATIONS)
def test_each_link_tolerance_equals_the_papers_formula(robot_name, q):
    robot = Manipulator.preset(robot_name)
    t = np.array([1e-3, 2e-3, 0.5e-3]) if q in ANGLES else np.array([0.02, 0.05, 0.01])
    b = max_pose_errors(robot, ClearanceSet(), POSES, tolerances={q: t})
    ref = paper_bounds(robot, POSES, {q: t})
    np.testing.assert_allclose(np.column_stack([b.dx_max, b.dy_max, b.dphi_max]), ref, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("q", LINK_VARIATIONS)
def test_worst_variation_of_each_parameter_attains_the_bound_in_the_papers_model(q):
    robot = Manipulator.preset("aalborg_3ppr")
    t = np.full(3, 1e-3 if q in ANGLES else 0.03)
    b = max_pose_errors(robot, ClearanceSet.load("case2"), POSES, tolerances={q: t}, details=True)
    clear = max_pose_errors(robot, ClearanceSet.load("case2"), POSES)
    for row, name in enumerate(("dx", "dy", "dphi")):
        e = pose_error(robot, POSES, b.worst_variations[name])        # the paper's Eq. 10, tolerances only
        np.testing.assert_allclose(e[:, row], getattr(b, f"{name}_max") - getattr(clear, f"{name}_max"),
                                   rtol=1e-10, atol=1e-15)
        assert np.all(np.isclose(np.abs(b.worst_variations[name][q]), t))


def fd_columns(robot: Manipulator, poses: np.ndarray, perturb, h: float) -> np.ndarray:
    """(n, 3, 3 legs) d pose / d parameter of each leg by central differences of the exact model."""
    ik = inverse_kinematics(robot, poses)
    act = np.take_along_axis(ik.joints, ik.actuated_index[None, :, None], axis=-1)[..., 0]
    cols = []
    for i in range(3):
        ends = [forward_kinematics(perturb(i, sign * h), act).nearest(poses) for sign in (1.0, -1.0)]
        d = ends[0] - ends[1]
        d[:, 2] = np.angle(np.exp(1j * d[:, 2]))
        cols.append(d / (2 * h))
    return np.stack(cols, axis=-1)


def generic_columns(robot: Manipulator, poses: np.ndarray, k: int, key: str) -> np.ndarray:
    """(n, 3, 3 legs) the first-order pose change per unit value of ``key`` on joint ``k`` of each leg."""
    ik = inverse_kinematics(robot, poses)
    cols = []
    for i in range(3):
        legs = [[JointErrors(), JointErrors(), JointErrors()] for _ in range(3)]
        legs[i][k] = JointErrors(**{key: 1.0})
        sources = ErrorSources(legs=tuple(tuple(leg) for leg in legs)).check(robot)
        signs = np.zeros((len(poses), 3))
        signs[:, i] = 1.0
        config = worst_configuration(robot, sources, ik.joints, poses, signs)
        st = robot.chains[i].state_at(ik.joints[:, i, :], poses)
        value = np.where(polar_coefficient(robot.chains[i], k, key, st, poses) < 0, -1.0, 1.0)
        cols.append(first_order_error(robot, ik.joints, poses, config) / value[:, None])
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("q, k, key", [("a", 0, "base_radius"), ("alpha", 0, "base_turn"),
                                       ("gamma", 0, "link_turn"), ("r", 2, "platform_radius"),
                                       ("psi", 2, "platform_turn")])
def test_polar_keys_on_a_3ppr_match_finite_differences_of_its_file_parameters(q, k, key):
    robot = Manipulator.preset("aalborg_3ppr")

    def perturb(i, delta):
        change = np.zeros(3)
        change[i] = delta
        return robot.perturbed(**{q: change})

    fd = fd_columns(robot, POSES, perturb, 1e-6)
    np.testing.assert_allclose(generic_columns(robot, POSES, k, key), fd, rtol=1e-6, atol=1e-9)


def _rpr_perturb(robot: Manipulator, key: str):
    data = robot.to_dict()

    def perturb(i, delta):
        legs = [dict(leg) for leg in data["legs"]]
        point = complex(*legs[i]["base" if key.startswith("base") else "platform"])
        if key.endswith("radius"):
            point = point * (1 + delta / abs(point))
        else:
            point = point * np.exp(1j * delta)
        legs[i]["base" if key.startswith("base") else "platform"] = [point.real, point.imag]
        return Manipulator.from_dict({**data, "legs": legs})

    return perturb


@pytest.mark.parametrize("key", ["base_radius", "base_turn", "platform_radius", "platform_turn"])
def test_polar_keys_on_a_3rpr_match_finite_differences_of_its_points(key):
    robot = Manipulator.preset("symmetric_3rpr")
    poses = np.array([[0.0, 0.0, 0.0], [8.0, -5.0, np.radians(6.0)], [-6.0, 9.0, np.radians(-9.0)]])
    k = 0 if key.startswith("base") else 2
    fd = fd_columns(robot, poses, _rpr_perturb(robot, key), 1e-6)
    np.testing.assert_allclose(generic_columns(robot, poses, k, key), fd, rtol=1e-6, atol=1e-9)


def test_polar_bounds_on_a_3rpr_are_the_best_vertex_of_the_tolerance_box():
    """Brute force over the 2^3 sign vertices of one key per leg, each vertex's error from finite differences."""
    robot = Manipulator.preset("symmetric_3rpr")
    poses = np.array([[3.0, -4.0, np.radians(5.0)], [-7.0, 2.0, np.radians(-4.0)]])
    t = np.array([0.01, 0.03, 0.02])
    for key in ("base_turn", "platform_radius"):
        k = 0 if key.startswith("base") else 2
        legs = [[JointErrors(), JointErrors(), JointErrors()] for _ in range(3)]
        for i in range(3):
            legs[i][k] = JointErrors(**{key: float(t[i] * (1e-2 if key.endswith("turn") else 1.0))})
        scale = np.array([legs[i][k].__getattribute__(key) for i in range(3)])
        b = max_pose_errors(robot, ErrorSources(legs=tuple(tuple(leg) for leg in legs)), poses)
        cols = fd_columns(robot, poses, _rpr_perturb(robot, key), 1e-6)          # (n, 3, legs)
        best = np.zeros((len(poses), 4))
        for signs in np.array(np.meshgrid(*[[-1.0, 1.0]] * 3)).reshape(3, -1).T:
            e = np.einsum("nql,l->nq", cols, signs * scale)
            best = np.maximum(best, np.column_stack([np.abs(e), np.hypot(e[:, 0], e[:, 1])]))
        np.testing.assert_allclose(np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max]), best, rtol=1e-5)


def _one(key: str, k: int, value: float = 1e-3) -> ErrorSources:
    legs = [[JointErrors(), JointErrors(), JointErrors()] for _ in range(3)]
    legs[0][k] = JointErrors(**{key: value})
    return ErrorSources(legs=tuple(tuple(leg) for leg in legs), name="polar")


@pytest.mark.parametrize("key, k, match", [("base_turn", 1, "the first joint"),
                                           ("platform_radius", 0, "the last joint"),
                                           ("link_turn", 2, "prismatic joints")])
def test_polar_key_on_the_wrong_joint_is_refused_by_name(key, k, match):
    with pytest.raises(ClearanceError, match=match) as info:
        _one(key, k).check(Manipulator.preset("aalborg_3ppr"))
    assert f"legs[1].joints[{k + 1}].{key}" in str(info.value)


def test_radius_key_at_the_origin_is_refused():
    data = Manipulator.preset("symmetric_3rpr").to_dict()
    data["legs"][0]["platform"] = [0.0, 0.0]
    robot = Manipulator.from_dict(data)
    with pytest.raises(ClearanceError, match="undefined"):
        _one("platform_radius", 2).check(robot)


def test_layers_without_the_polar_keys_refuse_them_by_name():
    robot = Manipulator.preset("symmetric_3rpr")
    sources = _one("base_turn", 0)
    for call in (lambda: certified_pose_errors(robot, sources, [0.0, 0.0, 0.0]),
                 lambda: as_sources(robot, sources),
                 lambda: pose_statistics(robot, sources, [0.0, 0.0, 0.0], samples=100)):
        with pytest.raises(ClearanceError, match="legs\\[1\\].joints\\[1\\].base_turn"):
            call()


def test_polar_keys_round_trip_through_the_clearance_file():
    text = _one("platform_turn", 2, 2e-3).to_toml()
    from pmaccuracy.model import _tomlio
    back = ErrorSources.from_dict(_tomlio.tomllib.loads(text))
    assert back.legs[0][2].platform_turn == 2e-3
    assert set(FIRST_ORDER_ONLY) <= set(JointErrors.__dataclass_fields__)


def test_cli_takes_polar_keys_in_bounds_and_refuses_them_in_certified(tmp_path, capsys):
    from pmaccuracy.cli import main
    path = tmp_path / "polar.toml"
    path.write_text(_one("base_turn", 0, 2e-4).to_toml(), encoding="utf-8")
    assert main(["bounds", "--robot", "symmetric_3rpr", "--clearances", str(path), "--pose", "1", "2", "3",
                 "--format", "json"]) == 0
    import json
    rec = json.loads(capsys.readouterr().out)[0]
    b = max_pose_errors("symmetric_3rpr", str(path), [1.0, 2.0, np.radians(3.0)])
    assert rec["dp_max"] == pytest.approx(float(b.dp_max), rel=1e-12) and rec["dp_max"] > 0
    assert main(["bounds", "--robot", "symmetric_3rpr", "--clearances", str(path), "--pose", "1", "2", "3",
                 "--certified"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "base_turn" in err and "certified" in err


def test_worst_configuration_keeps_every_source_when_several_act_at_one_joint():
    """A link turn adds a turn and a shift at the next joint, where that joint's own direction and position
    tolerances also act: the configuration must hold their sum (first order gives +-max exactly)."""
    robot = Manipulator.preset("aalborg_3ppr")
    sources = ErrorSources.from_clearance_set(ClearanceSet(), {"gamma": np.full(3, 1e-3), "theta": np.full(3, 2e-3),
                                                               "rho": np.full(3, 0.02)})
    legs = [list(leg) for leg in sources.legs]
    legs[0][1] = JointErrors(direction=2e-3, link_turn=1e-3)      # the bearing's link turn adds at joint 3
    sources = ErrorSources(legs=tuple(tuple(leg) for leg in legs)).check(robot)
    b = max_pose_errors(robot, sources, POSES, details=True)
    joints = inverse_kinematics(robot, POSES).joints
    for row, q in enumerate(("dx", "dy", "dphi")):
        e = first_order_error(robot, joints, POSES, worst_configuration(robot, sources, joints, POSES,
                                                                         b.worst_signs[q]))
        np.testing.assert_allclose(e[:, row], getattr(b, f"{q}_max"), rtol=1e-10)
