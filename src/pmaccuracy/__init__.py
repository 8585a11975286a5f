"""pmaccuracy: exact worst-case pose errors of planar parallel manipulators (any architecture) with joint clearances.

Implements and extends G. Wu, S. Bai, J. A. Kepler, S. Caro, "Error Modelling and
Experimental Validation of a Planar 3-PPR Parallel Manipulator with Joint
Clearances", ASME J. Mechanisms Robotics 4(4), 041011, 2012.

Units: lengths in mm and angles in radians in the API; files and the command
line use degrees (always in keys or options ending in ``deg``).

Start here (``import pmaccuracy as pm``); every function takes a robot and its clearances as objects,
preset names (``pm.Manipulator.preset_names()``) or paths to your own TOML files:

* your robot and clearances: ``robot = pm.load_robot("my_robot.toml")``,
  ``cl = pm.load_clearances("my_clearances.toml", robot)`` (guide: "File formats");
* exact first-order worst cases at poses ``(N, 3)`` [x mm, y mm, phi rad]:
  ``b = pm.max_pose_errors(robot, cl, poses)`` -> ``b.dx_max, b.dy_max, b.dphi_max, b.dp_max``;
* maps over the workspace: ``ds = pm.error_map(robot, cl, phis=[0.0, 0.5], n=101)`` (an xarray Dataset);
* certified bounds of the exact (nonlinear) model: ``pm.certified_pose_errors(robot, cl, poses)``;
* the certified worst case over a region: ``pm.global_worst(robot, cl, pm.make_region(robot, (lo, hi), box))``
  (a box, a ``pm.Disc`` or a ``pm.Polygon``; ``pm.largest_disc`` where targets hold);
* design: ``pm.synthesize`` (how loose may each joint be), ``pm.pose_statistics`` (Monte Carlo);
* calibration: ``pm.plan_poses``, ``pm.identify`` (from ``pm.read_calibration_csv``), ``pm.compensate``,
  ``pm.simulate_calibration`` (a virtual experiment), ``pm.calibration_report`` (its HTML report); spatial
  robots: ``pm.spatial_error_parameters``, ``pm.identify_spatial`` (from ``pm.read_spatial_csv``),
  ``pm.simulate_spatial_calibration``, ``pm.spatial_calibration_report``;
* kinematics: ``pm.inverse_kinematics``, ``pm.forward_kinematics``, ``pm.jacobians``, ``pm.singularity``;
* spatial robots (6-UPS, Delta, 3-RPS, 3-PRS, 3-UPU): the same kinematics with poses ``(N, 6)`` [x, y, z mm,
  rotation vector rad] (``pm.poses_from`` takes scipy ``Rotation`` objects), ``pm.complete_poses`` (controlled
  coordinates and parasitic motions), ``pm.assembly_modes`` (every real mode), ``pm.spatial_workspace``
  (guide: "Spatial robots"); their first-order worst cases ``pm.spatial_pose_errors`` and maps
  ``pm.spatial_error_map`` with ``pm.load_clearances(spec, robot)`` (guide: "Spatial error sources").

Every mistake in an input raises a subclass of :class:`PmAccuracyError` naming the file, key or argument.
The names are loaded lazily: ``import pmaccuracy`` itself imports nothing heavy.
"""

import importlib as _importlib

__version__ = "0.1.0"

#: Public name -> the module that defines it (loaded on first use).
_EXPORTS = {
    # errors
    **{name: "errors" for name in (
        "PmAccuracyError", "ConfigError", "GeometryError", "ClearanceError", "PoseError", "OutsideJointLimitsError",
        "SingularPoseError", "NoSolutionError", "CertificationError", "EmptyWorkspaceError", "MeasurementFileError",
        "VisionError", "UnsupportedArchitectureError", "MissingDependencyError")},
    "SingularRegionError": "accuracy.global_worst",
    "PlausibilityWarning": "model.plausibility",
    # the model: what a robot is, what its errors are
    "Manipulator": "model.manipulator", "Leg": "model.manipulator",
    **{name: "model.legs" for name in ("Chain", "Joint", "PPRLeg", "RPRLeg", "RRRLeg", "PRRLeg", "ChainLeg")},
    "SerialArm": "model.serial", "SerialJoint": "model.serial", "SerialErrorSources": "model.serial",
    "ErrorSources": "model.sources", "JointErrors": "model.sources", "JointDisplacements": "model.sources",
    "ClearanceSet": "model.clearances",
    "load_robot": "api", "load_clearances": "api", "export_robot": "api",
    # kinematics
    **{name: "kinematics" for name in ("FKSolution", "IKSolution", "forward_kinematics", "inverse_kinematics",
                                       "jacobians", "kinematic_jacobian", "singularity")},
    "constant_orientation_workspace": "kinematics.workspace",
    # spatial robots (issue 36)
    "SpatialManipulator": "model.spatial",
    **{name: "kinematics.spatial" for name in ("assembly_modes", "complete_poses", "poses_from",
                                               "poses_from_coordinates", "SpatialIK", "SpatialFK", "SpatialModes",
                                               "SpatialJacobians", "SpatialSingularity")},
    **{name: "kinematics.spatial_workspace" for name in ("spatial_workspace", "orientation_workspace_at",
                                                         "SpatialWorkspace")},
    "SpatialErrorSources": "model.spatial_sources", "SpatialJointErrors": "model.spatial_sources",
    "spatial_pose_errors": "accuracy.spatial_bounds", "spatial_error_components": "accuracy.spatial_bounds",
    "SpatialPoseErrors": "accuracy.spatial_bounds",
    **{name: "accuracy.spatial_maps" for name in ("spatial_error_map", "spatial_percentile_map",
                                                  "write_spatial_map")},
    "spatial_certified_bounds": "accuracy.spatial_nonlinear", "SpatialCertifiedBounds": "accuracy.spatial_nonlinear",
    "spatial_pose_statistics": "accuracy.spatial_statistics",
    **{name: "accuracy.spatial_worst" for name in ("spatial_region", "spatial_global_worst", "SpatialRegion",
                                                   "SpatialGlobalWorst", "SpatialQuantityWorst",
                                                   "SpatialSingularRegionError")},
    "spatial_synthesize": "accuracy.spatial_synthesis", "SpatialSynthesis": "accuracy.spatial_synthesis",
    "SpatialPoseStatistics": "accuracy.spatial_statistics",
    # accuracy
    "max_pose_errors": "accuracy.bounds", "PoseErrorBounds": "accuracy.bounds",
    "max_serial_errors": "model.serial",
    "certified_pose_errors": "accuracy.certified", "nonlinear_pose_errors": "accuracy.certified",
    "CertifiedPoseErrors": "accuracy.certified",
    "global_worst": "accuracy.global_worst", "make_region": "accuracy.global_worst",
    "Region": "accuracy.global_worst",
    "GlobalWorst": "accuracy.global_worst", "QuantityWorst": "accuracy.global_worst",
    "largest_disc": "accuracy.global_worst", "LargestDisc": "accuracy.global_worst",
    "Disc": "accuracy.regions", "Polygon": "accuracy.regions", "Rect": "accuracy.regions",
    "load_polygon": "accuracy.regions",
    "error_map": "accuracy.maps", "save_map": "accuracy.maps", "load_map": "accuracy.maps",
    "synthesize": "accuracy.synthesis", "Synthesis": "accuracy.synthesis",
    "pose_statistics": "accuracy.distributions", "PoseStatistics": "accuracy.distributions",
    **{name: "accuracy.loads" for name in ("Load", "LoadedError", "Statics", "loaded_pose_error", "statics",
                                           "WrenchSetErrors", "wrench_set_errors", "Preload", "design_preload",
                                           "loaded_error_map", "wrench_set_map", "RegionPreload",
                                           "design_region_preload", "certify_preload")},
    **{name: "accuracy.spatial_loads" for name in ("SpatialLoad", "SpatialStatics", "spatial_statics",
                                                   "SpatialLoadedError", "spatial_loaded_error", "SpatialPreload",
                                                   "spatial_design_preload", "SpatialWrenchSetErrors",
                                                   "spatial_wrench_set_errors", "spatial_loaded_error_map",
                                                   "spatial_wrench_set_map", "SpatialRegionPreload",
                                                   "spatial_design_region_preload", "SpatialSpringPreload",
                                                   "spatial_spring_preload")},
    **{name: "accuracy.serial_loads" for name in ("serial_statics", "SerialStatics", "loaded_serial_error",
                                                  "SerialLoadedError")},
    # calibration and compensation (issue 23)
    "error_parameters": "accuracy.calibration.parameters", "ParameterVector": "accuracy.calibration.parameters",
    "CalibrationData": "accuracy.calibration.data", "read_calibration_csv": "accuracy.calibration.data",
    "write_calibration_csv": "accuracy.calibration.data",
    "identify": "accuracy.calibration.identify", "Identification": "accuracy.calibration.identify",
    "Identifiability": "accuracy.calibration.identifiability",
    "plan_poses": "accuracy.calibration.plan", "Plan": "accuracy.calibration.plan",
    "compensate": "accuracy.calibration.compensate", "Compensation": "accuracy.calibration.compensate",
    "simulate_calibration": "accuracy.calibration.simulate", "Experiment": "accuracy.calibration.simulate",
    "calibration_report": "report.calibration_report",
    # calibration of spatial robots (issue 39, first increment)
    **{name: "accuracy.calibration.spatial_parameters" for name in ("spatial_error_parameters",
                                                                    "SpatialParameterVector")},
    **{name: "accuracy.calibration.spatial_identify" for name in ("identify_spatial", "SpatialIdentification",
                                                                  "SpatialCalibrationData")},
    **{name: "accuracy.calibration.spatial_data" for name in ("read_spatial_csv", "write_spatial_csv")},
    **{name: "accuracy.calibration.spatial_simulate" for name in ("simulate_spatial_calibration",
                                                                  "SpatialExperiment")},
    "spatial_calibration_report": "report.spatial_calibration_report",
}

__all__ = sorted(_EXPORTS) + ["__version__"]


#: The package's public subpackages and modules (attributes once imported, ``pm.accuracy.bounds``).
_SUBMODULES = ("accuracy", "api", "cli", "errors", "experiment", "io", "kinematics", "model", "numerics", "report",
               "vision")


def __getattr__(name: str):
    """Load a public name (or a submodule, ``pm.accuracy``) on first use."""
    module = _EXPORTS.get(name)
    if module is not None:
        value = getattr(_importlib.import_module(f".{module}", __name__), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):
        try:
            return _importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public names only: ``__all__`` and the subpackages (no helpers such as ``_importlib``)."""
    return sorted(set(__all__) | set(_SUBMODULES))
