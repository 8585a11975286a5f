"""``pmaccuracy calibrate plan | identify | compensate | simulate | report``: kinematic calibration and
compensation."""

from __future__ import annotations

import argparse

from . import _common

HELP = "kinematic calibration: plan poses, identify parameters from measurements, compensate, simulate"
_DEFAULT_HELP = ("Default: the robot's default of every command (case1 for a 3-PPR, the architecture's *_typical "
                 "preset otherwise, printed on stderr); 'none' for the model without clearances")
_SPATIAL_HELP = ". A spatial robot's: an error-source preset or file (default as above)"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help=HELP,
                       description="Kinematic calibration (mm and degrees in files and on the command line). "
                                   "plan: D-optimal measurement poses written as a calibration CSV; identify: the "
                                   "error parameters from a calibration CSV (or an experiment / vision batch "
                                   "file); compensate: commands of the identified robot for target poses; "
                                   "simulate: a virtual calibration experiment.")
    steps = p.add_subparsers(dest="step", metavar="STEP", required=True, parser_class=type(p))

    s = steps.add_parser("plan", help="choose N measurement poses (D-optimal) and write them as a calibration CSV")
    _common.add_robot(s)
    s.add_argument("--poses", type=_common.positive_int, default=30, metavar="N", help="poses to plan (default 30)")
    s.add_argument("--phi-range-deg", type=_common.finite_float, nargs=2, default=None, metavar=("LO", "HI"),
                   help="orientation range of the candidates, deg (default -20 20; parallel robots)")
    s.add_argument("--grid", type=_common.positive_int, default=None, metavar="N",
                   help="candidates per axis in x and y (default 22; 21 orientations; parallel robots). A serial "
                        "arm's candidates are 4000 seeded configurations within its joint ranges")
    s.add_argument("--seed", type=int, default=0, help="seed of the random choices compared with the plan")
    s.add_argument("--out", metavar="FILE.csv", help="write the plan: the calibration CSV to fill with readings; missing parent folders are created")
    s.add_argument("--target", type=_common.finite_float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help="spatial robot: plan for a laser tracker measuring these target points on the platform "
                        "(platform frame, mm; repeatable) instead of full poses")
    s.add_argument("--candidates", type=_common.positive_int, default=None, metavar="N",
                   help="spatial robot: random candidate poses drawn around home (default 20000; those within "
                        "every leg's limits are kept)")
    _common.add_format(s)
    s.set_defaults(func=run_plan)

    s = steps.add_parser("identify", help="identify the error parameters from a calibration CSV")
    _common.add_robot(s)
    s.add_argument("--data", required=True, metavar="FILE.csv",
                   help="calibration CSV: x,y,phi_deg and q1|q1_deg,q2..,q3.. (optional point, sigma_x, sigma_y, "
                        "sigma_phi_deg), or an experiment / vision batch measurement file")
    s.add_argument("--fix", action="append", default=[], metavar="NAME",
                   help="keep a parameter at nominal (repeatable), e.g. leg1.actuator.gain")
    s.add_argument("--frame", type=_common.finite_float, nargs="+", metavar="V",
                   help="starting pose of the measurement frame in the robot frame: X Y PHI_DEG (mm, mm, deg); a "
                        "spatial robot's X Y Z ROLL PITCH YAW (mm, deg; extrinsic x-y-z)")
    s.add_argument("--no-robust", action="store_true", help="plain least squares (no robust first pass)")
    s.add_argument("--clearances", metavar="FILE",
                   help="clearance preset or file: add each point's clearance pose covariance (first order, the "
                        "clearance states uniform in their sets, independent from point to point) to its "
                        "measurement covariance, so that the sigmas account for the clearances. " + _DEFAULT_HELP
                        + _SPATIAL_HELP)
    s.add_argument("--out", metavar="FILE.json", help="write the identification (read by calibrate compensate); missing parent folders are created")
    s.add_argument("--robot-out", metavar="FILE.toml", help="write the identified geometry as a robot file; missing parent folders are created")
    s.add_argument("--target", type=_common.finite_float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help="spatial robot, position-only data: a target point on the platform (platform frame, mm; "
                        "repeatable, in the order of the CSV's target numbers)")
    _common.add_format(s)
    s.set_defaults(func=run_identify)

    s = steps.add_parser("compensate", help="commands of the identified robot for target poses")
    s.add_argument("--identification", required=True, metavar="FILE.json", help="written by calibrate identify")
    s.add_argument("--pose", type=_common.finite_float, nargs=3, action="append", metavar=("X", "Y", "PHI_DEG"),
                   help="a target pose in the measurement frame (repeatable)")
    s.add_argument("--poses-csv", metavar="FILE", help="target poses from a CSV with columns x,y,phi_deg")
    s.add_argument("--clearances", metavar="FILE",
                   help="clearance preset or file: the clearance floor (worst case and RMS of the position and the "
                        "orientation) beside the prediction and the fit's RMS position residual (fit_rms_position). "
                        + _DEFAULT_HELP + " (of the identified robot)" + _SPATIAL_HELP)
    s.add_argument("--out", metavar="FILE.csv", help="write the compensated commands as a calibration CSV; missing parent folders are created")
    _common.add_format(s)
    s.set_defaults(func=run_compensate)

    s = steps.add_parser("simulate", help="virtual calibration: true robot, measurements, identify, compensate")
    _common.add_robot(s)
    s.add_argument("--poses", type=_common.positive_int, default=30, metavar="N", help="poses to plan (default 30)")
    s.add_argument("--seed", type=int, default=0, help="seed of the parameter errors, clearance states and noise")
    s.add_argument("--error-mm", type=float, default=None,
                   help="1-sigma of length and position errors of the true robot, mm (default 0.1)")
    s.add_argument("--error-deg", type=float, default=None,
                   help="1-sigma of angle errors of the true robot, deg (default 0.1)")
    s.add_argument("--errors", metavar="FILE.toml",
                   help="the true robot's parameter errors by name instead of random ones: name = value (mm, deg, "
                        "a gain's error as a fraction), e.g. \"leg1.base.x\" = 0.2; parameters not named stay "
                        "nominal")
    s.add_argument("--tolerances", metavar="FILE.toml",
                   help="the true robot's parameter errors drawn uniformly (seeded) within +- the named "
                        "tolerances: name = half-width (mm, deg, gain fraction); with --errors, added to them; "
                        "parameters not named stay nominal")
    s.add_argument("--noise-mm", type=float, default=0.01, help="1-sigma of the camera in x and y, mm")
    s.add_argument("--noise-deg", type=float, default=0.01, help="1-sigma of the camera in phi, deg")
    s.add_argument("--clearances", metavar="FILE",
                   help="clearance preset or file: random states in the measurements, and the clearance floor. "
                        + _DEFAULT_HELP + _SPATIAL_HELP)
    s.add_argument("--target", type=_common.finite_float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help="spatial robot: measure these target points on the platform (platform frame, mm; "
                        "repeatable) with a laser tracker instead of the full pose")
    s.add_argument("--noise-ppm", type=float, default=0.0,
                   help="spatial robot with --target: the tracker's distance-dependent 1-sigma, 1e-6 per mm of "
                        "distance, added to --noise-mm")
    s.add_argument("--plan", choices=("d-optimal", "random"), default=None,
                   help="spatial robot: the readings' poses, D-optimal out of the random candidates around home "
                        "(default) or the first random ones (to compare)")
    s.add_argument("--data-out", metavar="FILE.csv",
                   help="write the simulated measurements as a calibration CSV (input of calibrate identify); missing parent folders are created")
    s.add_argument("--report", metavar="FILE.html",
                   help="also write the calibration report (self-contained HTML) of the run; missing parent folders "
                        "are created")
    s.add_argument("--photos", metavar="DIR",
                   help="measure the planned poses from photos: render each into DIR/<point>.png (flat test camera, "
                        "DIR/manifest.csv lists the commands) and measure them as 'vision pose' does, with the "
                        "photos' own sigmas (instead of --noise-mm/--noise-deg); the folder is created if missing")
    s.add_argument("--mm-per-pixel", type=float, default=None, metavar="S",
                   help="scale of the photos' flat camera, mm per pixel, 0.01-1 (default 0.25; with --photos; markers "
                        "of 1.5 mm radius or 6 px, whichever is larger)")
    _common.add_format(s)
    s.set_defaults(func=run_simulate)
    _register_report(steps)


#: Options of ``calibrate report`` that describe a simulation (not allowed with --data), with their defaults.
_SIMULATION_DEFAULTS = {"poses": 30, "seed": 0, "error_mm": 0.1, "error_deg": 0.1, "noise_mm": 0.01,
                        "noise_deg": 0.01}


def _register_report(steps) -> None:
    s = steps.add_parser("report", help="write the calibration report (self-contained HTML): of a virtual "
                                        "experiment, or of measured data and their identification",
                         description="The calibration report: residual maps before and after, parameter estimates "
                                     "with 1-sigma error bars, the singular value spectrum and what cannot be "
                                     "identified, observability against random and grid choices, and the accuracy "
                                     "before and after beside the clearance floor. From a virtual experiment "
                                     "(--robot, --poses, --seed, --error-* or --errors / --tolerances, --noise-*, "
                                     "--clearances, as calibrate simulate) or from measurements: --data FILE.csv with --identification "
                                     "FILE.json (written by calibrate identify from the same data).")
    s.add_argument("--out", required=True, metavar="FILE.html",
                   help="the report (self-contained HTML); missing parent folders are created")
    _common.add_robot(s)
    s.add_argument("--data", metavar="FILE.csv", help="measured calibration CSV (with --identification)")
    s.add_argument("--identification", metavar="FILE.json",
                   help="identification of --data, written by calibrate identify --out")
    s.add_argument("--clearances", metavar="FILE",
                   help="clearance preset or file: the clearance floor (and, simulating, random clearance states "
                        "in the measurements). " + _DEFAULT_HELP)
    s.add_argument("--poses", type=_common.positive_int, metavar="N", help="simulation: poses to plan (default 30)")
    s.add_argument("--seed", type=int, help="seed of the simulation, the random pose choices and the floor's "
                                            "samples (default 0)")
    for name, what in (("--error-mm", "simulation: 1-sigma of length and position errors, mm (default 0.1)"),
                       ("--error-deg", "simulation: 1-sigma of angle errors, deg (default 0.1)"),
                       ("--noise-mm", "simulation: 1-sigma of the camera in x and y, mm (default 0.01)"),
                       ("--noise-deg", "simulation: 1-sigma of the camera in phi, deg (default 0.01)")):
        s.add_argument(name, type=float, help=what)
    s.add_argument("--errors", metavar="FILE.toml",
                   help="simulation: the true robot's parameter errors by name (as calibrate simulate --errors: "
                        "name = value in mm, deg or gain fraction); parameters not named stay nominal")
    s.add_argument("--tolerances", metavar="FILE.toml",
                   help="simulation: the true robot's errors drawn uniformly (seeded) within +- the named "
                        "tolerances (as calibrate simulate --tolerances); parameters not named stay nominal")
    s.set_defaults(func=run_report)


def _clearances(args: argparse.Namespace, robot):
    """The clearances of a calibrate step for ``robot``: ``--clearances``, or the default of every command
    (:func:`pmaccuracy.cli._common.clearances_or_default`, named on stderr); ``none`` gives None, the
    calibration model without clearances (the all-zero set would give the same fit, plus a floor of 0)."""
    clearances = _common.clearances_or_default(args, robot)
    return None if clearances == "none" else clearances


def _write_report(path, ident, data, *, experiment=None, clearances=None, seed=0, args=None) -> None:
    from ..report.calibration_report import calibration_report

    calibration_report(path, ident, data, experiment=experiment, clearances=clearances, seed=seed,
                       command=_common.command_line(args) if args is not None else None)


def run_report(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy.calibration.data import read_calibration_csv
    from ..accuracy.calibration.records import read_identification
    from ..accuracy.calibration.parameters import error_parameters
    from ..accuracy.calibration.simulate import load_parameter_table, simulate_calibration
    from ..errors import ConfigError

    _common.prepare_output(args.out, "--out", (".html",))
    measured = args.data is not None or args.identification is not None
    if measured:
        if args.data is None or args.identification is None:
            missing = "--data" if args.data is None else "--identification"
            raise ConfigError("a report of measurements needs both --data FILE.csv and --identification FILE.json",
                              key=missing)
        if args.robot != "aalborg_3ppr":
            raise ConfigError("not with --data: the robot is the one of --identification", key="--robot")
        given = [k for k in (*_SIMULATION_DEFAULTS, "errors", "tolerances")
                 if k != "seed" and getattr(args, k) is not None]
        if given:
            raise ConfigError("describes a simulation: not with --data (the robot and its identification come "
                              "from --identification)", key="--" + given[0].replace("_", "-"))
    named = args.errors is not None or args.tolerances is not None
    for opt in ("error_mm", "error_deg"):
        if named and getattr(args, opt) is not None:
            raise ConfigError("not with --errors or --tolerances (they give the true robot's errors)",
                              key="--" + opt.replace("_", "-"))
    values = {k: (v if getattr(args, k) is None else getattr(args, k)) for k, v in _SIMULATION_DEFAULTS.items()}
    for opt in ("error_mm", "error_deg", "noise_mm", "noise_deg"):
        v = values[opt]
        if not (np.isfinite(v) and v >= 0):
            raise ConfigError(f"must be a finite number >= 0, got {v!r}", key="--" + opt.replace("_", "-"))
    if measured:
        ident = read_identification(args.identification)
        if getattr(ident.parameters.robot, "dimension", 3) == 6:
            return _report_spatial(args, ident=ident)
        data = read_calibration_csv(args.data, ident.parameters)
        try:
            _write_report(args.out, ident, data, clearances=_clearances(args, ident.parameters.robot),
                          seed=values["seed"], args=args)
        except ConfigError as exc:
            if exc.key != "poses" or exc.source is not None:
                raise
            raise ConfigError(exc.message, source=args.data, key="--data") from None
        print(f"wrote {args.out}: calibration report of {len(data)} measured points ({args.data})")
        return 0
    robot = _robot(args)
    if getattr(robot, "dimension", 3) == 6:
        return _report_spatial(args, robot)
    pv = error_parameters(robot)
    clearances = _clearances(args, pv.robot)
    errors = None if args.errors is None else load_parameter_table(args.errors, pv, "errors")
    tolerances = None if args.tolerances is None else load_parameter_table(args.tolerances, pv, "tolerances")
    sigma = None if named else {"mm": values["error_mm"], "rad": np.radians(values["error_deg"])}
    noise = (max(values["noise_mm"], 1e-9), max(values["noise_mm"], 1e-9), max(np.radians(values["noise_deg"]), 1e-11))
    ex = _simulated(args, simulate_calibration, pv, values["poses"], seed=values["seed"], noise=noise,
                    clearances=clearances, error_sigma=sigma, errors=errors, tolerances=tolerances)
    _write_report(args.out, ex.identification, ex.data, experiment=ex, seed=values["seed"], args=args)
    print(f"wrote {args.out}: calibration report of a virtual experiment ({pv.robot.name}, {len(ex.data)} points)")
    return 0


def _simulated(args: argparse.Namespace, simulate, *posargs, **kwargs):
    """``simulate(*posargs, **kwargs)`` (:func:`~pmaccuracy.accuracy.calibration.simulate.simulate_calibration`);
    a true robot whose errors are too large to be calibrated is blamed on the file or options that gave them."""
    from ..errors import ConfigError

    try:
        return simulate(*posargs, **kwargs)
    except ConfigError as exc:
        blamed = {"errors": args.errors, "tolerances": args.tolerances,
                  "errors and tolerances": f"{args.errors} with {args.tolerances}"}
        if exc.source is None and exc.key in blamed:
            raise ConfigError(exc.message, source=blamed[exc.key]) from None
        if exc.source is None and exc.key == "error_sigma":
            given = [f"--{k.replace('_', '-')}" for k in ("error_mm", "error_deg") if getattr(args, k) is not None]
            raise ConfigError(exc.message, key=" and ".join(given) or "--error-mm/--error-deg (defaults)") from None
        raise


#: Steps of ``calibrate`` that take spatial robots so far.
SPATIAL_STEPS = ("plan", "identify", "simulate", "report")


def _robot(args: argparse.Namespace):
    """The parallel robot or, for a file with ``architecture = "serial"``, the serial arm of ``--robot``; a
    spatial robot for :data:`SPATIAL_STEPS`."""
    from . import serial_cmd
    from ..model.spatial import is_spatial

    if getattr(args, "step", None) in SPATIAL_STEPS and not serial_cmd.is_serial_robot(args.robot):
        robot = _common.robot_arg(args.robot)
        if is_spatial(robot):
            return robot
    if serial_cmd.is_serial_robot(args.robot):
        from ..model.serial import SerialArm

        return SerialArm.load(args.robot)
    return _common.load_robot(args)


def _estimates(ident) -> list[dict]:
    """One row per parameter of a planar or spatial identification (angles in degrees)."""
    import numpy as np

    rows = []
    for e in ident.estimates():
        deg = e["unit"] == "rad"
        f = np.degrees if deg else float
        rows.append({"parameter": e["name"], "unit": "deg" if deg else e["unit"], "nominal": f(e["nominal"]),
                     "estimate": f(e["estimate"]), "change": f(e["estimate"] - e["nominal"]),
                     "sigma": f(e["sigma"]) if e["identified"] else None,
                     "status": "identified" if e["identified"] else "fixed"})
    return rows


def _summary(ident) -> dict:
    from ..accuracy.calibration.identify import identification_to_dict

    d = identification_to_dict(ident)
    # a unit in every printed name: the whitened residuals are in multiples of the readings' stated sigmas
    names = {"rms_before": "rms_before_sigmas", "rms_after": "rms_after_sigmas",
             "fit_rms_position": "fit_rms_position_mm"}
    return {**{names.get(k, k): v for k, v in d["fit"].items()}, "condition": d["identifiability"]["condition"],
            **{k: d["identifiability"][k] for k in ("O1", "O2", "O3", "O4")},
            "identified": len(ident.identifiability.identified), "fixed": list(ident.identifiability.fixed)}


def _print_identification(ident, fmt: str) -> None:
    rows = _estimates(ident)
    if fmt == "json":
        from ..accuracy.calibration.identify import identification_to_dict

        _common.emit({"estimates": rows, **identification_to_dict(ident)}, "json")
    elif fmt == "csv":
        _common.emit(rows, "csv")
    else:
        _common.emit(rows, "table")
        print()
        _common.emit([_summary(ident)], "table")
        for sentence in ident.identifiability.combinations:
            print(f"note: {sentence}")
    if ident.flagged and fmt != "json":   # the JSON record lists them (fit.outlier_points)
        import sys

        out = sys.stdout if fmt == "table" else sys.stderr
        print(f"note: {len(ident.flagged)} of {ident.n_points} points left out as outliers (forward residual above "
              f"{ident.outlier_threshold:.3g} predicted sigmas):", file=out)
        for o in ident.flagged:
            print(f"outlier: {o.describe()}", file=out)


def run_plan(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy.calibration.data import write_calibration_csv
    from ..accuracy.calibration.parameters import error_parameters
    from ..accuracy.calibration.plan import candidate_poses, plan_poses
    from ..errors import ConfigError, EmptyWorkspaceError
    from ..model.serial import SerialArm

    lo, hi = args.phi_range_deg or (-20.0, 20.0)
    if not lo <= hi:
        raise ConfigError(f"empty range [{lo:g}, {hi:g}] deg", key="--phi-range-deg")
    if args.out:
        _common.prepare_output(args.out, "--out", (".csv",))
    robot = _robot(args)
    if getattr(robot, "dimension", 3) == 6:
        return _plan_spatial(args, robot)
    for opt in ("target", "candidates"):
        if getattr(args, opt):
            raise ConfigError("only for a spatial robot", key="--" + opt)
    pv = error_parameters(robot)
    if isinstance(robot, SerialArm):
        for opt, value in (("--grid", args.grid), ("--phi-range-deg", args.phi_range_deg)):
            if value is not None:
                raise ConfigError("a serial arm's candidates are configurations within its joint ranges: this "
                                  "option is for parallel robots", key=opt)
        cand = None
    else:
        try:
            cand = candidate_poses(pv, n=args.grid or 22, phi_range=(np.radians(lo), np.radians(hi)))
        except EmptyWorkspaceError as exc:
            given = [o for o, v in (("--phi-range-deg", args.phi_range_deg), ("--grid", args.grid)) if v is not None]
            raise ConfigError(f"{exc} at orientations {lo:g} to {hi:g} deg on a {args.grid or 22} x "
                              f"{args.grid or 22} grid", key=" and ".join(given) or "--robot") from None
    plan = plan_poses(pv, args.poses, cand, seed=args.seed)
    if args.out:
        write_calibration_csv(pv.robot, plan.commands, None, args.out)
    rows = [{"choice": name, **idx} for name, idx in (("planned", plan.index), ("random (mean of 20)", plan.random_index),
                                                       ("grid", plan.grid_index))]
    if args.format == "json":
        _common.emit({"robot": pv.robot.name, "candidates": plan.n_candidates, "indices": rows,
                      "poses": [{"x": p[0], "y": p[1], "phi_deg": np.degrees(p[2])} for p in plan.poses]}, "json")
    elif args.format == "csv":
        _common.emit(rows, "csv")
    else:
        print(f"{len(plan.poses)} poses of {plan.n_candidates} candidates; observability indices:")
        _common.emit(rows, "table")
    return 0


def run_identify(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    import numpy as np
    import tomli_w

    from ..accuracy.calibration.data import read_calibration_csv
    from ..accuracy.calibration.identify import identification_to_dict, identify
    from ..accuracy.calibration.parameters import error_parameters, robot_file

    for opt, path, kinds in (("--out", args.out, (".json",)), ("--robot-out", args.robot_out, (".toml",))):
        if path:
            _common.prepare_output(path, opt, kinds)
    robot = _robot(args)
    if getattr(robot, "dimension", 3) == 6:
        return _identify_spatial(args, robot)
    from ..errors import ConfigError

    if args.target:
        raise ConfigError("only for a spatial robot's position-only data", key="--target")
    if args.frame is not None and len(args.frame) != 3:
        raise ConfigError(f"a planar robot's frame is X Y PHI_DEG (3 numbers), got {len(args.frame)}", key="--frame")
    pv = error_parameters(robot)
    pv.index(args.fix)
    data = read_calibration_csv(args.data, pv)
    frame = None if args.frame is None else np.array([args.frame[0], args.frame[1], np.radians(args.frame[2])])
    ident = identify(data, pv, fixed=tuple(args.fix), frame=frame, robust=not args.no_robust,
                     clearances=_clearances(args, pv.robot))
    if args.out:
        Path(args.out).write_text(json.dumps(identification_to_dict(ident), indent=2), encoding="utf-8")
    if args.robot_out:
        Path(args.robot_out).write_text(tomli_w.dumps(robot_file(pv, ident.values)), encoding="utf-8")
    _print_identification(ident, args.format)
    return 0


def run_compensate(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy.calibration.compensate import compensate
    from ..accuracy.calibration.data import write_calibration_csv
    from ..accuracy.calibration.parameters import actuators
    from ..accuracy.calibration.records import read_identification

    if args.out:
        _common.prepare_output(args.out, "--out", (".csv",))
    ident = read_identification(args.identification)
    if getattr(ident.parameters.robot, "dimension", 3) == 6:
        return _compensate_spatial(args, ident)
    targets = _common.poses_from_args(args.pose, args.poses_csv)
    comp = compensate(ident, targets, clearances=_clearances(args, ident.parameters.robot))
    pv = ident.parameters
    if args.out:
        write_calibration_csv(pv.robot, comp.commands, None, args.out)
    kinds = [kind for kind, _ in actuators(pv.robot)]
    rows = []
    for n, t in enumerate(comp.targets):
        row = {"x": t[0], "y": t[1], "phi_deg": np.degrees(t[2])}
        for k, kind in enumerate(kinds):
            f = np.degrees if kind == "R" else float
            name = f"q{k + 1}_deg" if kind == "R" else f"q{k + 1}"
            row[name] = f(comp.commands[n, k])
            row[f"{name}_nominal"] = f(comp.nominal_commands[n, k])
        row["predicted_sigma_p"] = float(np.hypot(*comp.predicted_sigma[n, :2]))
        row["predicted_sigma_phi_deg"] = float(np.degrees(comp.predicted_sigma[n, 2]))
        row["fit_rms_position"] = comp.fit_rms_position
        if comp.floor_dp_max is not None:
            row["floor_dp_max"] = float(comp.floor_dp_max[n])
            row["floor_dp_rms"] = float(comp.floor_dp_rms[n])
            row["floor_dphi_max_deg"] = float(np.degrees(comp.floor_dphi_max[n]))
            row["floor_dphi_rms_deg"] = float(np.degrees(comp.floor_dphi_rms[n]))
        rows.append(row)
    _common.emit(rows, args.format)
    return 0


def run_simulate(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy.calibration.parameters import error_parameters
    from ..accuracy.calibration.data import write_calibration_csv
    from ..accuracy.calibration.simulate import simulate_calibration
    from ..errors import ConfigError

    from ..accuracy.calibration.simulate import load_parameter_table

    for opt in ("error_mm", "error_deg", "noise_mm", "noise_deg"):
        v = getattr(args, opt)
        if v is not None and not (np.isfinite(v) and v >= 0):
            raise ConfigError(f"must be a finite number >= 0, got {v!r}", key="--" + opt.replace("_", "-"))
    named = args.errors is not None or args.tolerances is not None
    for opt in ("error_mm", "error_deg"):
        if named and getattr(args, opt) is not None:
            raise ConfigError("not with --errors or --tolerances (they give the true robot's errors)",
                              key="--" + opt.replace("_", "-"))
    if args.data_out:
        _common.prepare_output(args.data_out, "--data-out", (".csv",))
    if args.report:
        _common.prepare_output(args.report, "--report", (".html",))
    measure_with = None
    if args.mm_per_pixel is not None and not args.photos:
        raise ConfigError("only with --photos DIR", key="--mm-per-pixel")
    robot = _robot(args)
    if getattr(robot, "dimension", 3) == 6:
        return _simulate_spatial(args, robot)
    for opt in ("target", "noise_ppm", "plan"):
        if getattr(args, opt):
            raise ConfigError("only for a spatial robot", key="--" + opt.replace("_", "-"))
    clearances = _clearances(args, robot)
    if args.photos:
        from ..vision.calibration_photos import PHOTO_MM_PER_PIXEL, photo_measurer

        scale = PHOTO_MM_PER_PIXEL if args.mm_per_pixel is None else args.mm_per_pixel
        if not (np.isfinite(scale) and 0.01 <= scale <= 1.0):
            raise ConfigError(f"must be within [0.01, 1] mm per pixel, got {scale!r}", key="--mm-per-pixel")
        folder = _common.prepare_output(args.photos, "--photos", folder=True)
        measure_with = photo_measurer(folder, mm_per_pixel=scale, clearances=clearances)
    pv = error_parameters(robot)
    errors = None if args.errors is None else load_parameter_table(args.errors, pv, "errors")
    tolerances = None if args.tolerances is None else load_parameter_table(args.tolerances, pv, "tolerances")
    sigma = None if named else {"mm": 0.1 if args.error_mm is None else args.error_mm,
                                "rad": np.radians(0.1 if args.error_deg is None else args.error_deg)}
    noise = (max(args.noise_mm, 1e-9), max(args.noise_mm, 1e-9), max(np.radians(args.noise_deg), 1e-11))
    ex = _simulated(args, simulate_calibration, pv, args.poses, seed=args.seed, noise=noise,
                    clearances=clearances, error_sigma=sigma, measure_with=measure_with, errors=errors,
                    tolerances=tolerances)
    ident = ex.identification
    if args.data_out:
        d = ex.data
        write_calibration_csv(pv.robot, d.commands, d.poses, args.data_out, sigmas=d.sigmas)
    if args.report:
        _write_report(args.report, ident, ex.data, experiment=ex, seed=args.seed, args=args)
    before = np.hypot(*ex.errors_before[:, :2].T)
    after = np.hypot(*ex.errors_after[:, :2].T)
    summary = {"points": ident.n_points, "identified": len(ident.identifiability.identified),
               "fixed": len(ident.identifiability.fixed), "outliers": len(ident.outliers),
               "max_error_before_mm": float(before.max()), "max_error_after_mm": float(after.max()),
               "rms_error_before_mm": float(np.sqrt(np.mean(before ** 2))),
               "rms_error_after_mm": float(np.sqrt(np.mean(after ** 2)))}
    if ex.compensation.floor_dp_max is not None:
        summary["floor_dp_max_mm"] = float(ex.compensation.floor_dp_max.max())
    if args.format == "json":
        rows = _estimates(ident)
        for row, unit, true in zip(rows, pv.units, ex.true):   # the true robot beside the estimates
            row["true"] = float(np.degrees(true)) if unit == "rad" else float(true)
        _common.emit({"summary": summary, "estimates": rows}, "json")
    elif args.format == "csv":
        _common.emit([summary], "csv")
    else:
        _common.emit([summary], "table")
    return 0


# ---------------------------------------------------------------------------------------------- spatial robots
def _spatial_record(ident) -> dict:
    from ..accuracy.calibration.spatial_identify import spatial_identification_to_dict

    return spatial_identification_to_dict(ident)


def _print_spatial(ident, fmt: str, extra: dict | None = None) -> None:
    rows = _estimates(ident)
    record = _spatial_record(ident)
    if fmt == "json":
        _common.emit({"estimates": rows, **record, **(extra or {})}, "json")
        return
    if fmt == "csv":
        _common.emit(rows, "csv")
        return
    _common.emit(rows, "table")
    print()
    fit = record["fit"]
    _common.emit([{**{k: v for k, v in fit.items() if k != "outlier_rows"}, "outliers": len(fit["outlier_rows"]),
                   "identified": len(ident.identifiability.identified),
                   "fixed": len(ident.identifiability.fixed), **(extra or {})}], "table")
    for sentence in ident.identifiability.combinations:
        print(f"note: {sentence}")
    for row in fit["outlier_rows"]:
        print(f"outlier: row {row} left out (its reading disagrees with the fitted robot)")


def _targets(args):
    import numpy as np

    return None if not args.target else np.array(args.target, dtype=float)


def _identify_spatial(args: argparse.Namespace, robot) -> int:
    import json
    from pathlib import Path

    import tomli_w

    from ..accuracy.calibration.spatial_data import read_spatial_csv
    from ..accuracy.calibration.spatial_identify import identify_spatial
    from ..accuracy.calibration.spatial_parameters import spatial_error_parameters, spatial_robot_file

    pv = spatial_error_parameters(robot, targets=_targets(args))
    pv.index(args.fix)
    start = None if args.frame is None else _spatial_start(pv, args.frame)
    sources = _spatial_sources(args, robot)
    data = read_spatial_csv(args.data, pv)
    ident = identify_spatial(data, pv, fixed=tuple(args.fix), robust=not args.no_robust, start=start,
                             clearances=sources)
    if args.out:
        Path(args.out).write_text(json.dumps(_common._plain(_spatial_record(ident)), indent=2), encoding="utf-8")
    if args.robot_out:
        Path(args.robot_out).write_text(tomli_w.dumps(spatial_robot_file(pv, ident.values)), encoding="utf-8")
    _print_spatial(ident, args.format)
    return 0


def _spatial_sources(args: argparse.Namespace, robot):
    """The spatial error sources of ``--clearances`` (default: the architecture's typical preset, said on stderr;
    a chain robot, which has none: no clearances, said too; ``none``: no clearances, None)."""
    from ..errors import ClearanceError, PmAccuracyError
    from ..model.spatial_sources import SpatialErrorSources, default_preset

    if args.clearances is None:
        try:
            args.clearances = default_preset(robot)
            _common.announce_default_clearances(args.clearances, args)
        except ClearanceError:      # a chain robot: the readings' sigmas alone unless a file is given
            args.clearances = "none"
            _common.announce_default_clearances(f"none, no preset for a {robot.architecture} robot", args)
    if args.clearances == "none":
        return None
    try:
        return SpatialErrorSources.load(args.clearances, robot)
    except PmAccuracyError as exc:
        if "--clearances" in str(exc):
            raise
        raise type(exc)(f"--clearances: {exc}") from None


def _spatial_start(pv, frame):
    """The identification's start: the nominal with ``--frame X Y Z ROLL PITCH YAW`` (the device frame's pose in
    the robot's base frame, mm and deg, as a planar robot's) turned into the frame parameters (the base frame in
    the device's: ``R_F = R_d^T``, ``t_F = -R_d^T t_d``)."""
    import numpy as np

    from ..errors import ConfigError
    from ..numerics.spatial import euler_xyz_to_rotvec, rotations, rotvecs

    if len(frame) != 6:
        raise ConfigError(f"a spatial robot's frame is X Y Z ROLL PITCH YAW (6 numbers: mm, deg), got {len(frame)}",
                          key="--frame")
    Rd = rotations(euler_xyz_to_rotvec(np.array(frame[3:]), degrees=True))
    start = pv.nominal.copy()
    start[pv.frame_index] = np.concatenate([-Rd.T @ np.array(frame[:3]), rotvecs(Rd.T[None])[0]])
    return start


def _simulate_spatial(args: argparse.Namespace, robot) -> int:
    import numpy as np

    from ..accuracy.calibration.simulate import load_parameter_table, true_parameters
    from ..accuracy.calibration.spatial_compensate import residuals_beside_floor
    from ..accuracy.calibration.spatial_data import write_spatial_csv
    from ..accuracy.calibration.spatial_parameters import spatial_error_parameters
    from ..accuracy.calibration.spatial_simulate import simulate_spatial_calibration
    from ..errors import ConfigError

    for opt in ("photos", "mm_per_pixel"):
        if getattr(args, opt) is not None:
            raise ConfigError("not for a spatial robot yet", key="--" + opt.replace("_", "-"))
    if not (np.isfinite(args.noise_ppm) and args.noise_ppm >= 0):
        raise ConfigError(f"must be a finite number >= 0, got {args.noise_ppm!r}", key="--noise-ppm")
    if args.noise_ppm and not args.target:
        raise ConfigError("only with --target (a laser tracker's readings)", key="--noise-ppm")
    pv = spatial_error_parameters(robot, targets=_targets(args))
    sources = _spatial_sources(args, robot)
    sigma = {"mm": 0.1 if args.error_mm is None else args.error_mm,
             "rad": np.radians(0.1 if args.error_deg is None else args.error_deg)}
    true = None
    if args.errors is not None or args.tolerances is not None:      # as a planar robot's: the nominal plus those
        errors = None if args.errors is None else load_parameter_table(args.errors, pv, "errors")
        tolerances = None if args.tolerances is None else load_parameter_table(args.tolerances, pv, "tolerances")
        true = true_parameters(pv, args.seed, None, errors=errors, tolerances=tolerances)
    ex = simulate_spatial_calibration(pv, args.poses, seed=args.seed, error_sigma=sigma,
                                      noise=(args.noise_mm, np.radians(args.noise_deg)), ppm=args.noise_ppm,
                                      clearances=sources, plan=args.plan or "d-optimal", true=true)
    if args.data_out:
        write_spatial_csv(pv, ex.data, args.data_out)
    if args.report:
        from ..report.spatial_calibration_report import spatial_calibration_report

        spatial_calibration_report(args.report, ex.identification, ex.data, experiment=ex,
                                   command=_common.command_line(args))
    z = ex.normalized_errors()
    extra = {"max_abs_normalized_error": float(np.max(np.abs(z))) if z.size else None,
             "rms_normalized_error": float(np.sqrt(np.mean(z ** 2))) if z.size else None,
             "plan": args.plan or "d-optimal",
             "max_error_before_mm": float(np.nanmax(ex.errors_before[:, 0])),
             "max_error_after_mm": float(np.nanmax(ex.errors_after[:, 0]))}
    comp = ex.compensation
    extra["max_predicted_sigma_after_mm"] = float(np.nanmax(comp.predicted_sigma[:, 0]))
    if sources is not None:
        fit = residuals_beside_floor(ex.identification, ex.data, sources)
        kept = ~fit["outlier"]
        extra.update({"max_residual_mm": float(np.nanmax(fit["residual_mm"][kept])),
                      "floor_readings_dp_max_mm": float(np.nanmax(fit["floor"]["dp_max"][kept])),
                      "readings_within_floor": f"{int(np.sum(fit['within'] & kept))} of {int(kept.sum())}",
                      "floor_dp_max_mm": float(np.nanmax(comp.floor["dp_max"])),
                      "targets_within_floor": f"{int(np.sum(ex.errors_after[:, 0] <= comp.floor['dp_max'] + 3 * comp.predicted_sigma[:, 0]))} of {len(ex.targets)}"})
    if args.format == "json":
        extra["true"] = dict(zip(pv.names, (float(v) for v in ex.true)))
        if ex.plan is not None:
            extra["observability"] = {"planned": ex.plan.index, "random": ex.plan.random_index}
    _print_spatial(ex.identification, args.format, extra)
    return 0


def _report_spatial(args: argparse.Namespace, robot=None, ident=None) -> int:
    """``calibrate report`` of a spatial robot: a virtual experiment of ``robot`` or the readings ``--data`` of
    the identification ``ident``."""
    import numpy as np

    from ..accuracy.calibration.simulate import load_parameter_table, true_parameters
    from ..accuracy.calibration.spatial_data import read_spatial_csv
    from ..accuracy.calibration.spatial_parameters import spatial_error_parameters
    from ..accuracy.calibration.spatial_simulate import simulate_spatial_calibration
    from ..errors import ConfigError
    from ..report.spatial_calibration_report import spatial_calibration_report

    if ident is not None:
        for opt in ("errors", "tolerances"):
            if getattr(args, opt) is not None:
                raise ConfigError("describes a virtual experiment's true robot; a report of --data has none",
                                  key="--" + opt)
        data = read_spatial_csv(args.data, ident.parameters)
        sources = _spatial_sources(args, ident.parameters.robot)
        spatial_calibration_report(args.out, ident, data, clearances=sources, command=_common.command_line(args))
        print(f"wrote {args.out}: calibration report of {len(data)} readings ({args.data})")
        return 0
    pv = spatial_error_parameters(robot)
    sources = _spatial_sources(args, robot)
    values = {k: (v if getattr(args, k) is None else getattr(args, k)) for k, v in _SIMULATION_DEFAULTS.items()}
    true = None
    if args.errors is not None or args.tolerances is not None:      # as calibrate simulate: the nominal plus those
        errors = None if args.errors is None else load_parameter_table(args.errors, pv, "errors")
        tolerances = None if args.tolerances is None else load_parameter_table(args.tolerances, pv, "tolerances")
        true = true_parameters(pv, values["seed"], None, errors=errors, tolerances=tolerances)
    ex = simulate_spatial_calibration(pv, values["poses"], seed=values["seed"],
                                      error_sigma={"mm": values["error_mm"], "rad": np.radians(values["error_deg"])},
                                      noise=(values["noise_mm"], np.radians(values["noise_deg"])), clearances=sources,
                                      true=true)
    spatial_calibration_report(args.out, ex.identification, ex.data, experiment=ex, command=_common.command_line(args))
    print(f"wrote {args.out}: calibration report of a virtual experiment ({pv.robot.name}, {len(ex.data)} readings)")
    return 0


def _plan_spatial(args: argparse.Namespace, robot) -> int:
    import numpy as np

    from ..accuracy.calibration.spatial_data import write_spatial_csv
    from ..accuracy.calibration.spatial_identify import SpatialCalibrationData
    from ..accuracy.calibration.spatial_parameters import spatial_error_parameters
    from ..accuracy.calibration.spatial_plan import plan_spatial_poses
    from ..errors import ConfigError
    from ..kinematics.spatial import coordinates

    for opt in ("phi_range_deg", "grid"):
        if getattr(args, opt) is not None:
            raise ConfigError("for planar robots (a spatial robot's candidates: --candidates)",
                              key="--" + opt.replace("_", "-"))
    pv = spatial_error_parameters(robot, targets=_targets(args))
    plan = plan_spatial_poses(pv, args.poses, n_candidates=args.candidates or 20000, seed=args.seed)
    if args.out:
        T = max(pv.n_targets, 1)
        k = 6 if pv.kind == "pose" else 3
        n = len(plan.commands) * T
        labels = tuple(str(i) for i in np.repeat(np.arange(1, len(plan.commands) + 1), T))
        sig = np.tile([0.01] * 3 + [np.radians(0.01)] * 3, (n, 1))[:, :k]
        blank = SpatialCalibrationData(labels, np.repeat(plan.commands, T, axis=0), np.full((n, k), np.nan), sig,
                                       np.tile(np.arange(T), len(plan.commands)), "<plan>")
        write_spatial_csv(pv, blank, args.out)
    rows = [{"choice": name, **idx} for name, idx in (("planned", plan.index), ("random (mean of 5)",
                                                                                  plan.random_index))]
    if args.format == "json":
        c = coordinates(plan.poses, degrees=True)
        _common.emit({"robot": pv.robot.name, "candidates": plan.n_candidates, "indices": rows,
                      "poses": [dict(zip(("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg"), map(float, p)))
                                for p in c]}, "json")
    elif args.format == "csv":
        _common.emit(rows, "csv")
    else:
        print(f"{len(plan.poses)} poses of {plan.n_candidates} candidates; observability indices:")
        _common.emit(rows, "table")
    return 0


def _compensate_spatial(args: argparse.Namespace, ident) -> int:
    import numpy as np

    from .._textfile import read_csv
    from ..accuracy.calibration.spatial_compensate import compensate_spatial
    from ..accuracy.calibration.spatial_data import spatial_command_columns
    from ..errors import ConfigError, MeasurementFileError
    from ..io.csvio import write_csv_columns
    from ..kinematics.spatial import poses_from_coordinates

    if args.pose or not args.poses_csv:
        raise ConfigError("a spatial robot's targets come from --poses-csv FILE with columns x,y,z,roll_deg,"
                          "pitch_deg,yaw_deg (device frame, mm and deg)", key="--pose" if args.pose else "--poses-csv")
    sources = _spatial_sources(args, ident.parameters.robot)
    names = ("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg")
    lines = read_csv(args.poses_csv, MeasurementFileError)
    header = [h.strip() for h in lines[0][1]] if lines else []
    missing = [c for c in names if c not in header]
    if missing:
        raise MeasurementFileError(f"header must name {','.join(names)} (missing {','.join(missing)})",
                                   source=args.poses_csv, key="line 1")
    rows = []
    for line, row in lines[1:]:
        if not row or all(not c.strip() for c in row):
            continue
        try:
            vals = [float(row[header.index(c)]) for c in names]
        except (ValueError, IndexError):
            raise MeasurementFileError("x,y,z,roll_deg,pitch_deg,yaw_deg must be numbers", source=args.poses_csv,
                                       key=f"line {line}") from None
        if not np.all(np.isfinite(vals)):
            raise MeasurementFileError("values must be finite", source=args.poses_csv, key=f"line {line}")
        rows.append(vals)
    if not rows:
        raise MeasurementFileError("no data rows", source=args.poses_csv)
    comp = compensate_spatial(ident, poses_from_coordinates(np.array(rows), degrees=True), clearances=sources)
    pv = ident.parameters
    kinds = np.array([k == "R" for k in pv.robot.actuated_kinds])
    out = {}
    coords = np.array(rows)
    for k, n in enumerate(names):
        out[n] = coords[:, k]
    for k, name in enumerate(spatial_command_columns(pv.robot)):
        f = np.degrees if kinds[k] else (lambda v: v)
        out[name] = f(comp.commands[:, k])
        out[f"{name}_nominal"] = f(comp.nominal_commands[:, k])
    out["predicted_sigma_p"] = comp.predicted_sigma[:, 0]
    out["predicted_sigma_angle_deg"] = np.degrees(comp.predicted_sigma[:, 1])
    if comp.floor is not None:
        out["floor_dp_max"] = comp.floor["dp_max"]
        out["floor_dp_rms"] = comp.floor["dp_rms"]
        out["floor_dtheta_max_deg"] = np.degrees(comp.floor["dtheta_max"])
        out["floor_dtheta_rms_deg"] = np.degrees(comp.floor["dtheta_rms"])
    if args.out:
        write_csv_columns({k: v for k, v in out.items() if k.startswith("q") and not k.endswith("_nominal")
                           or k in names}, args.out)
    _common.emit([{k: float(v[i]) for k, v in out.items()} for i in range(len(rows))], args.format)
    return 0
