"""Degrees passed where the API takes radians warn (issue 25): every public function taking poses or
orientations issues one :class:`PlausibilityWarning` for ``phi = 15`` (15 deg typed as radians: 859 deg),
pointing at the caller's line, and stays silent for the same orientation in radians, ``np.radians(15)``.

The rule (:func:`pmaccuracy.model.plausibility.looks_like_degrees`): ``|phi| > 2 pi``; checked here against
its definition on both sides of the threshold, written independently of the code.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest

import pmaccuracy as pm
from pmaccuracy.errors import PmAccuracyError
from pmaccuracy.model import plausibility
from pmaccuracy.model.plausibility import PlausibilityWarning

#: Where the calls that write a file write it (removed at exit).
_SCRATCH = tempfile.TemporaryDirectory(prefix="pmaccuracy-units-")

PPR = "aalborg_3ppr"
RRR = "symmetric_3rrr"
DEG15 = math.radians(15.0)


def _pose(phi: float) -> list[list[float]]:
    return [[0.0, 0.0, phi]]


def _measurements(phi: float):
    from pmaccuracy.experiment.virtual_rig import simulate_readings
    m = simulate_readings(PPR, "case1", _pose(DEG15), seed=1)
    return dataclasses.replace(m, nominal=np.array(_pose(phi)))


def _repeats(phi: float):
    from pmaccuracy.experiment.iso9283 import simulate_repeats
    r = simulate_repeats(PPR, "case1", _pose(DEG15), 3, model="first_order", seed=1)
    return dataclasses.replace(r, nominal=np.array(_pose(phi)))


def _fk_q(phi: float) -> np.ndarray:
    """Actuator values (rad) of symmetric_3rrr at its home pose; for ``phi = 15`` the first one is 15 (degrees
    typed in)."""
    q = pm.inverse_kinematics(RRR, [0.0, 0.0, 0.0]).q.copy()
    if phi == 15.0:
        q[0] = 15.0
    return q


def _serial_q(phi: float) -> list[float]:
    return [phi, 0.3, -0.3]


def _calls():
    """name -> (function of an orientation in rad that calls the public function, names covered)."""
    from pmaccuracy.accuracy.designs import compare_designs
    from pmaccuracy.accuracy.distributions import region_statistics
    from pmaccuracy.accuracy.maps import write_zarr_map
    from pmaccuracy.experiment import compare
    from pmaccuracy.experiment.iso9283 import compare_repeatability, predicted_repeatability, simulate_repeats
    from pmaccuracy.experiment.virtual_rig import simulate_experiment, simulate_readings
    arm = pm.load_robot("planar_3r_arm")
    return {
        "max_pose_errors": lambda phi: pm.max_pose_errors(PPR, "case1", _pose(phi)),
        "inverse_kinematics": lambda phi: pm.inverse_kinematics(PPR, _pose(phi)),
        "jacobians": lambda phi: pm.jacobians(PPR, _pose(phi)),
        "kinematic_jacobian": lambda phi: pm.kinematic_jacobian(PPR, _pose(phi)),
        "singularity": lambda phi: pm.singularity(PPR, _pose(phi)),
        "forward_kinematics": lambda phi: pm.forward_kinematics(RRR, _fk_q(phi)),   # revolute actuators, rad
        "constant_orientation_workspace": lambda phi: pm.constant_orientation_workspace(PPR, phi),
        "error_map": lambda phi: pm.error_map(PPR, "case1", phi, n=5),
        "certified_pose_errors": lambda phi: pm.certified_pose_errors(PPR, "case1", _pose(phi), search=False),
        "nonlinear_pose_errors": lambda phi: pm.nonlinear_pose_errors(PPR, "case1", _pose(phi)),
        "make_region": lambda phi: pm.make_region(PPR, (phi, phi), (-5.0, 5.0, -5.0, 5.0)),
        "global_worst": lambda phi: pm.global_worst(PPR, "case1", _region(), candidates=np.array(_pose(phi)),
                                                    grid=3, gap=0.05),
        "pose_statistics": lambda phi: pm.pose_statistics(PPR, "case1", [0.0, 0.0, phi], samples=200),
        "max_serial_errors": lambda phi: pm.max_serial_errors(arm, "arm_typical", _serial_q(phi)),
        "serial_statics": lambda phi: pm.serial_statics(arm, _serial_q(phi), pm.Load(fx=1.0)),
        "loaded_serial_error": lambda phi: pm.loaded_serial_error(arm, "arm_typical", _serial_q(phi),
                                                                  pm.Load(fx=1.0)),
        "region_statistics": lambda phi: region_statistics(PPR, "case1", [phi], grid=4, samples=100),
        "compare_designs": lambda phi: compare_designs([PPR], ["case1"], [phi], n=5),
        "simulate_readings": lambda phi: simulate_readings(PPR, "case1", _pose(phi), seed=1),
        "simulate_experiment": lambda phi: simulate_experiment(PPR, "case1", phi, grid=2, seed=1),
        "compare": lambda phi: compare(PPR, "case1", _measurements(phi)),
        "predicted_repeatability": lambda phi: predicted_repeatability(PPR, "case1", _pose(phi), 3, tests=3),
        "simulate_repeats": lambda phi: simulate_repeats(PPR, "case1", _pose(phi), 3, model="first_order"),
        "compare_repeatability": lambda phi: compare_repeatability(PPR, "case1", _repeats(phi), tests=3),
        "statics": lambda phi: pm.statics(PPR, _pose(phi), pm.Load(fx=1.0)),
        "plan_poses": lambda phi: pm.plan_poses(pm.error_parameters(pm.load_robot(RRR)), 12,
                                                np.array([[x, y, phi] for x in (-5.0, 0.0, 5.0)
                                                          for y in (-5.0, 0.0, 5.0)] * 2)),
        "largest_disc": lambda phi: pm.largest_disc(PPR, "case1", (0.0, 0.0), (phi, phi), {"dp": 0.5}, tol=10.0),
        "loaded_pose_error": lambda phi: pm.loaded_pose_error(PPR, "case1", _pose(phi), pm.Load(fx=1.0),
                                                              exact=False),
        "wrench_set_errors": lambda phi: pm.wrench_set_errors(PPR, "case1", _pose(phi), [1.0, 0, 0], [1.0, 1, 1]),
        "design_preload": lambda phi: pm.design_preload(PPR, "case1", _pose(phi)[0], [0.0, 0, 0], [1.0, 1, 1]),
        "loaded_error_map": lambda phi: pm.loaded_error_map(PPR, "case1", pm.Load(fx=1.0), [phi], n=5),
        "wrench_set_map": lambda phi: pm.wrench_set_map(PPR, "case1", [0.0, 0, 0], [1.0, 1, 1], [phi], n=5),
    }


def _region():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return pm.make_region(PPR, (DEG15, DEG15), (-1.0, 1.0, -1.0, 1.0))


def _spatial_calls():
    """The spatial robots' functions: rotation vectors, roll/pitch/yaw and a Delta's arm angles in rad."""
    hexapod, delta, head = (pm.load_robot(n) for n in ("stewart_6ups", "delta_clavel", "rps_3"))

    def pose(phi):
        return [0.0, 0.0, 400.0, 0.0, 0.0, phi]
    return {
        "poses_from": lambda phi: pm.poses_from([0.0, 0.0, 400.0], [0.0, 0.0, phi]),
        "poses_from_coordinates": lambda phi: pm.poses_from_coordinates([0.0, 0.0, 400.0, 0.0, 0.0, phi]),
        "complete_poses": lambda phi: pm.complete_poses(head, [350.0, phi, 0.0]),
        "assembly_modes": lambda phi: pm.assembly_modes(delta, [phi, 0.4, 0.4]),
        "spatial_workspace": lambda phi: pm.spatial_workspace(hexapod, [0.0, 0.0, phi], n=8, tilt=False),
        "spatial_inverse_kinematics": lambda phi: pm.inverse_kinematics(hexapod, pose(phi)),
        "spatial_jacobians": lambda phi: pm.jacobians(hexapod, pose(phi)),
        "spatial_singularity": lambda phi: pm.singularity(hexapod, pose(phi)),
        "spatial_pose_errors": lambda phi: pm.spatial_pose_errors(hexapod, pm.load_clearances("ups_typical", hexapod),
                                                                  pose(phi)),
        "spatial_error_components": lambda phi: pm.spatial_error_components(
            hexapod, pm.load_clearances("ups_typical", hexapod), pose(phi)),
        "spatial_certified_bounds": lambda phi: pm.spatial_certified_bounds(hexapod, "ups_typical", pose(phi),
                                                                            ascent_steps=0),
        "spatial_pose_statistics": lambda phi: pm.spatial_pose_statistics(hexapod, "ups_typical", pose(phi),
                                                                          samples=1000),
        "spatial_synthesize": lambda phi: pm.spatial_synthesize(hexapod, pm.load_clearances("ups_typical", hexapod),
                                                                {"dp": 0.1}, n=5, orientation=[0.0, 0.0, phi]),
        "spatial_statics": lambda phi: pm.spatial_statics(hexapod, pose(phi), pm.SpatialLoad(force=(0, 0, -1.0))),
        "spatial_loaded_error": lambda phi: pm.spatial_loaded_error(hexapod, "ups_typical", pose(phi),
                                                                    pm.SpatialLoad(force=(0, 0, -1.0))),
        "spatial_design_preload": lambda phi: pm.spatial_design_preload(hexapod, "ups_typical", pose(phi),
                                                                        [0, 0, -1.0, 0, 0, 0], [1.0] * 6),
        "spatial_statics_front_door": lambda phi: pm.statics(hexapod, pose(phi), pm.SpatialLoad(force=(0, 0, -1.0))),
        "spatial_loaded_pose_error": lambda phi: pm.loaded_pose_error(hexapod, "ups_typical", pose(phi),
                                                                      pm.SpatialLoad(force=(0, 0, -1.0))),
        "spatial_design_preload_front_door": lambda phi: pm.design_preload(hexapod, "ups_typical", pose(phi),
                                                                           [0, 0, -1.0, 0, 0, 0], [1.0] * 6),
        "spatial_wrench_set_errors": lambda phi: pm.spatial_wrench_set_errors(hexapod, "ups_typical", pose(phi),
                                                                              [0, 0, -1.0, 0, 0, 0], [1.0] * 6),
        "spatial_wrench_set_errors_front_door": lambda phi: pm.wrench_set_errors(hexapod, "ups_typical", pose(phi),
                                                                                 [0, 0, -1.0, 0, 0, 0], [1.0] * 6),
        "spatial_spring_preload": lambda phi: pm.spatial_spring_preload(hexapod, "ups_typical", pose(phi),
                                                                        [0, 0, -1.0, 0, 0, 0], [1.0] * 6),
        "spatial_loaded_error_map": lambda phi: pm.spatial_loaded_error_map(
            hexapod, "ups_typical", pm.SpatialLoad(force=(0, 0, -1.0)), n=3, orientation=[0.0, 0.0, phi]),
        "spatial_wrench_set_map": lambda phi: pm.spatial_wrench_set_map(
            hexapod, "ups_typical", [0, 0, -1.0, 0, 0, 0], [1.0] * 6, n=3, orientation=[0.0, 0.0, phi],
            preload=False),
        "spatial_region": lambda phi: pm.spatial_region(hexapod, box=(-1.0, 1.0, -1.0, 1.0, 399.0, 401.0),
                                                        orientation=[0.0, 0.0, phi]),
        "spatial_error_map": lambda phi: pm.spatial_error_map(hexapod, pm.load_clearances("ups_typical", hexapod),
                                                              n=5, orientation=[0.0, 0.0, phi]),
        "spatial_percentile_map": lambda phi: pm.spatial_percentile_map(
            hexapod, pm.load_clearances("ups_typical", hexapod), n=4, samples=1000, orientation=[0.0, 0.0, phi]),
        "write_spatial_map": lambda phi: pm.write_spatial_map(
            Path(_SCRATCH.name) / "m.nc", hexapod, pm.load_clearances("ups_typical", hexapod), n=4,
            orientation=[0.0, 0.0, phi]),
    }


CALLS = {**_calls(), **_spatial_calls()}
#: Public functions of the front door that take no pose or orientation (why).
NO_ORIENTATION = {
    "load_robot": "a robot spec", "export_robot": "a robot spec and a file path", "load_clearances": "a clearance spec", "save_map": "a dataset and a path",
    "load_map": "a path (the map's phi coordinate is in degrees)",
    "synthesize": "a Region, checked where it is made (make_region)",
    "spatial_design_region_preload": "a SpatialRegion, checked where it is made (spatial_region)",
    "load_polygon": "a polygon file (mm)",
    "error_parameters": "a robot", "read_calibration_csv": "a file (phi_deg, checked by the reader)",
    "write_calibration_csv": "a CalibrationData and a path", "identify": "a CalibrationData (read from a file)",
    "simulate_calibration": "a parameter vector and counts (poses are planned inside)",
    "compensate": "an Identification and targets: checked like plan_poses' candidates (tested there)",
    "calibration_report": "an Identification and CalibrationData (read from files)",
    "design_region_preload": "a Region, checked where it is made (make_region)",
    "certify_preload": "a Region, checked where it is made (make_region)",
    "orientation_workspace_at": "a position (mm); the orientations are generated inside",
    "spatial_global_worst": "a SpatialRegion, checked where it is made (spatial_region)",
    "spatial_error_parameters": "a robot and target points (mm)",
    "read_spatial_csv": "a file (roll_deg, pitch_deg, yaw_deg, checked by the reader)",
    "write_spatial_csv": "a SpatialCalibrationData and a path",
    "identify_spatial": "a SpatialCalibrationData (read from a file)",
    "simulate_spatial_calibration": "a parameter vector and counts (poses are drawn inside)",
    "spatial_calibration_report": "a SpatialIdentification and SpatialCalibrationData (read from files)",
}


def test_every_public_function_is_decided():
    functions = {n for n in pm.__all__ if inspect.isfunction(getattr(pm, n))}
    assert functions - set(CALLS) - set(NO_ORIENTATION) == set()


def _plausibility(caught) -> list:
    return [w for w in caught if issubclass(w.category, PlausibilityWarning)]


@pytest.mark.parametrize("name", sorted(CALLS))
def test_degrees_warn_once_at_the_callers_line(name):
    call = CALLS[name]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            call(15.0)
        except PmAccuracyError:   # 15 rad may well lie outside the robot's ranges: the warning came first
            pass
    found = _plausibility(caught)
    assert len(found) == 1, [str(w.message) for w in found]
    message = str(found[0].message)
    assert "15 rad = 859.4 deg" in message and "np.radians(15)" in message and "\n" not in message
    assert found[0].filename == __file__   # the user's line, not the library's


@pytest.mark.parametrize("name", sorted(CALLS))
def test_radians_are_silent(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # any warning fails, and so does any error
        CALLS[name](DEG15)


@pytest.mark.parametrize("value, warns", [
    (2 * math.pi, False), (-2 * math.pi, False), (math.pi, False), (-3.0, False), (6.28, False),
    (6.2832, True), (7.0, True), (-10.0, True), (15.0, True), (90.0, True), (360.0, True),
])
def test_rule_is_a_full_turn(value, warns):
    assert bool(plausibility.looks_like_degrees(value)) is warns
    assert bool(plausibility.degree_slip_messages([0.0, value], "phis")) is warns


def test_non_finite_and_malformed_values_are_left_to_the_functions():
    assert not plausibility.looks_like_degrees(np.array([np.nan, np.inf, -np.inf])).any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plausibility.check_orientations("abc", "phi")
        plausibility.check_orientations([[1.0, 2.0]], "poses", poses=True)


def test_several_slips_make_one_line():
    with pytest.warns(PlausibilityWarning) as record:
        pm.inverse_kinematics(PPR, [[0.0, 0.0, 10.0], [0.0, 0.0, 0.1], [0.0, 0.0, -20.0]])
    assert len(record) == 1
    assert str(record[0].message).startswith("poses[..., 2]: 2 of 3 orientations beyond a full turn (2 pi rad), "
                                             "e.g. 10 rad = 573 deg")


def test_command_line_does_not_warn_twice(capsys):
    from pmaccuracy.cli import main
    # 0.2618 deg looks like radians to the command line (one warning); the API sees 0.00457 rad: silent
    assert main(["bounds", "--clearances", "case1", "--pose", "0", "0", "0.2618"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "looks like radians" in err[0]
    # 900 deg is 15.7 rad for the API, but the command line's angles are degrees by construction: no warning
    assert main(["ik", "--pose", "0", "0", "720"]) == 0
    assert capsys.readouterr().err == ""


# ----------------------------------------------------------------------------------- other silent slips
def test_clearances_and_tolerances_built_in_python_are_checked_like_files():
    """The loaders warn about clearances in unlikely units; objects built in Python now do too (once)."""
    from pmaccuracy.model.sources import ErrorSources, JointErrors
    with pytest.warns(PlausibilityWarning, match=r"ClearanceSet: legs\[1,2,3\].bearing_angle = 0.0688 rad") as rec:
        pm.ClearanceSet(bearing_angle=0.0688, revolute_radial=0.01)   # 0.0688 deg typed where rad are expected
    assert len(rec) == 1 and rec[0].filename == __file__
    z = JointErrors()
    with pytest.warns(PlausibilityWarning, match=r"ErrorSources: legs\[1,2,3\].joints\[2\].angular = 0.07 rad"):
        ErrorSources(legs=((z, JointErrors(angular=0.07), z),) * 3)
    with pytest.warns(PlausibilityWarning, match=r"tolerances: legs\[1,2,3\].theta_rad = 1 rad"):
        pm.max_pose_errors(PPR, pm.ClearanceSet(), [0.0, 0.0, 0.0], tolerances={"theta": 1.0})
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # presets, files and the package's own objects: silent
        for robot, name in ((PPR, "case1"), (PPR, "case2"), (RRR, "rrr_typical"), (RRR, "rrr_tolerances")):
            pm.max_pose_errors(robot, pm.load_clearances(name, robot), [0.0, 0.0, 0.0])
        pm.ClearanceSet(bearing_angle=0.0012, guide_lateral=0.005, revolute_radial=0.01).scaled(2.0)
        pm.max_pose_errors(PPR, pm.ClearanceSet(), [0.0, 0.0, 0.0], tolerances={"theta": 0.001})


@pytest.mark.parametrize("call, error, words", [
    (lambda: pm.make_region(PPR, 0.3, None), pm.ConfigError, ["phi", "two numbers"]),
    (lambda: pm.make_region(PPR, (0.0, 0.1, 0.2), None), pm.ConfigError, ["phi", "two numbers"]),
    (lambda: pm.make_region(PPR, (0.0, 0.1), (0, 1, 2)), pm.ConfigError, ["box", "four numbers"]),
    (lambda: pm.error_map(PPR, "case1", [[0.0, 0.1]], n=5), pm.ConfigError, ["phis", "(1, 2)"]),
    (lambda: pm.error_map(PPR, "case1", [], n=5), pm.ConfigError, ["phis", "non-empty"]),
    (lambda: pm.pose_statistics(PPR, "case1", [[0, 0, 0], [1, 1, 0]], samples=10), pm.PoseError,
     ["one pose", "(2, 3)"]),
    (lambda: pm.global_worst(PPR, "case1", _region(), candidates=np.zeros((2, 2))), pm.PoseError,
     ["candidates", "(2, 2)"]),
])
def test_wrong_shapes_are_refused_by_name(call, error, words):
    with pytest.raises(error) as err:
        call()
    assert all(w in str(err.value) for w in words), str(err.value)
