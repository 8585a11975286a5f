"""``pmaccuracy experiment ...``: the paper's experimental validation (Sec. 5.2 and 6, Eq. 23-24, Figs. 9-15).

Sub-commands:

* ``simulate`` - a virtual experiment: the push protocol played on a simulated
  rig over a grid of the workspace at one orientation, written as a
  measurement CSV (``point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg``);
* ``compare`` - measured errors of a CSV (Eq. 23) against the model's maxima
  (Eq. 21-22) at the same nominal poses: RMSD (paper convention and twice the
  maxima), sample standard deviations, ISO 9283 accuracy (Eq. 24), the band
  check of Fig. 15; with ``--out DIR`` also figures, ``comparison.json`` and a
  self-contained ``report.html``; with ``--repeats R.csv`` (repeated attained poses, ``simulate --repeats N``)
  also ISO 9283 pose accuracy and repeatability beside the repeatability the clearance model predicts
  (:mod:`pmaccuracy.experiment.iso9283`); with ``--push-n N`` (the rig's push force) also each push's
  measured displacement beside the loaded model's prediction (:class:`pmaccuracy.experiment.PushComparison`).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from .. import experiment
from ..report import experiment_report
from ..io.resolve import load_clearances
from . import _common
from .bounds_cmd import add_clearances

_QUANTITIES = experiment.QUANTITIES
#: Columns of the ISO 9283 table of ``compare --repeats``.
_ISO_TABLE = ("point", "n", "ap_p", "ap_phi_deg", "rp_l", "rp_l_model", "rp_l_model_lo", "rp_l_model_hi",
              "rp_phi_deg", "rp_phi_model_deg", "rp_phi_model_lo_deg", "rp_phi_model_hi_deg")


#: Columns of the push table of ``compare --push-n``.
_PUSH_TABLE = ("point", "push", "dx_meas", "dx_pred", "dx_diff", "dx_range", "dy_meas", "dy_pred", "dy_diff",
               "dy_range", "dphi_deg_meas", "dphi_deg_pred", "dphi_deg_diff", "dphi_deg_range", "inside")


def _add_common(p: argparse.ArgumentParser) -> None:
    _common.add_robot(p)
    add_clearances(p)


def register(sub: argparse._SubParsersAction) -> None:
    ep = sub.add_parser(
        "experiment", help="experimental validation: simulate the push protocol, compare measurements with the model",
        description="Experimental validation of the clearance model (paper Sec. 5.2, 6). Measurement files are CSV "
                    "with columns point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg (mm, deg); push is one of "
                    "+x,-x,+y,-y,+r,-r and every point has all six.")
    esub = ep.add_subparsers(dest="experiment_command", metavar="SUBCOMMAND", parser_class=type(ep))
    esub.required = True

    sp = esub.add_parser(
        "simulate", help="virtual experiment on a grid of the workspace, written as a measurement CSV",
        description="At each grid point inside the workspace at PHI, each push (+x,-x,+y,-y,+r,-r) drives the "
                    "clearances to the worst-case configuration of that direction (scaled by --take-up); the "
                    "reading is the exact loop closure (default) or the first-order model, plus Gaussian camera "
                    "noise.")
    _add_common(sp)
    sp.add_argument("--phi-deg", type=_common.angle_deg, default=0.0, metavar="PHI",
                    help="platform orientation in degrees (default: 0)")
    sp.add_argument("--grid", type=int, default=5, metavar="N",
                    help="N x N lattice over the workspace's bounding box; points inside are measured (default: 5)")
    sp.add_argument("--take-up", type=_common.finite_float, default=1.0, metavar="F",
                    help="fraction of the clearance a push takes up, in [0, 1] (default: 1)")
    sp.add_argument("--push-n", type=_common.finite_float, default=None, metavar="N",
                    help="push with a force of N newtons (a moment of N times the robot's size for +-r): every "
                         "clearance is taken up along its joint's reaction (the loaded model of `pmaccuracy load`); "
                         "a leg the push leaves unloaded keeps its clearances centred. Default: each push drives "
                         "the clearances to the worst case of its direction")
    sp.add_argument("--noise-mm", type=_common.finite_float, default=experiment.DEFAULT_ACCURACY_MM, metavar="S",
                    help=f"camera noise on x and y, standard deviation in mm (default: "
                         f"{experiment.DEFAULT_ACCURACY_MM:g})")
    sp.add_argument("--noise-deg", type=_common.finite_float, default=experiment.DEFAULT_ACCURACY_DEG, metavar="S",
                    help=f"camera noise on phi, standard deviation in deg (default: "
                         f"{experiment.DEFAULT_ACCURACY_DEG:g})")
    sp.add_argument("--model", choices=experiment.MODELS, default="exact",
                    help="readings from the exact loop closure (default) or the first-order model (Eq. 19)")
    sp.add_argument("--seed", type=_common.nonnegative_int, default=0, help="seed of the noise (default: 0)")
    sp.add_argument("--out", required=True, metavar="M.csv", help="measurement CSV file to write; missing parent folders are created")
    sp.add_argument("--repeats", type=_common.positive_int, default=None, metavar="N",
                    help="also a virtual ISO 9283 test: N attained poses per point, each cycle a fresh random "
                         "clearance state inside the sets (N >= 2), written to --repeats-out")
    sp.add_argument("--repeats-out", metavar="R.csv",
                    help="repeated-pose CSV (point,x_nom,y_nom,phi_nom_deg,cycle,x,y,phi_deg) of --repeats "
                         "(default: M_repeats.csv beside --out); missing parent folders are created")
    sp.add_argument("--distribution", metavar="FILE",
                    help="laws of the clearance states of --repeats: uniform (default), truncnormal, boundary or "
                         "a TOML file (see pmaccuracy statistics)")
    _common.add_format(sp)
    sp.set_defaults(func=run_simulate)

    cp = esub.add_parser(
        "compare", help="measured errors (Eq. 23) vs predicted maxima (Eq. 21-22): RMSD, SSD, accuracy, figures",
        description="Reads a measurement CSV, computes dx, dy, dphi (ranges of the six readings) and dp (largest "
                    "+t/-t distance) per point (Eq. 23) and compares them with the exact maxima at the nominal poses. "
                    "'rmsd' follows the paper (measured range - maximum); 'rmsd_width_consistent' uses twice the "
                    "maxima (a range spans both sides of the symmetric error set). JSON has everything; table and "
                    "csv list the points (table also the RMSD).")
    _add_common(cp)
    cp.add_argument("--measurements", required=True, metavar="M.csv", help="measurement CSV file")
    cp.add_argument("--out", metavar="DIR", help="also write figures, comparison.json and report.html into DIR (created with its missing parents)")
    cp.add_argument("--accuracy-mm", type=_common.finite_float, default=experiment.DEFAULT_ACCURACY_MM, metavar="A",
                    help="position accuracy of the measurement system, mm (Fig. 15 band +-2A; default: 0.01)")
    cp.add_argument("--accuracy-deg", type=_common.finite_float, default=experiment.DEFAULT_ACCURACY_DEG,
                    metavar="A", help="orientation accuracy of the measurement system, deg (default: 0.01)")
    cp.add_argument("--limit-tolerance-mm", type=_common.finite_float,
                    default=experiment.NOMINAL_LIMIT_TOLERANCE_MM, metavar="T",
                    help="accept nominal poses up to T mm outside the joint ranges (default: 0.005, the encoder "
                         "accuracy)")
    cp.add_argument("--push-n", type=_common.finite_float, default=None, metavar="N",
                    help="the rig's push force in newtons (a moment of N times the robot's size for +-r), if known: "
                         "each push's measured displacement (reading - nominal) beside the loaded model's "
                         "prediction, their difference and whether it lies inside the predicted range (unloaded "
                         "legs' spread + 2 x the accuracy); JSON key 'pushes', a second table, and with --format csv "
                         "one row per point and push instead of one per point")
    cp.add_argument("--map-grid", type=int, default=41, metavar="N",
                    help="grid of the background error maps with --out (default: 41)")
    cp.add_argument("--repeats", metavar="R.csv",
                    help="repeated attained poses (point,x_nom,y_nom,phi_nom_deg,cycle,x,y,phi_deg): ISO 9283 "
                         "AP and RP per point beside the RP the clearance model predicts (fresh clearance state "
                         "each cycle, camera noise of sd --accuracy-mm/--accuracy-deg)")
    cp.add_argument("--distribution", metavar="FILE",
                    help="laws of the clearance states for the predicted RP: uniform (default), truncnormal, "
                         "boundary or a TOML file (see pmaccuracy statistics)")
    _common.add_format(cp)
    cp.set_defaults(func=run_compare)


#: The library's keyword of each experiment parameter -> the option that sets it (errors name the option).
_OPTIONS = {"take_up": "--take-up", "noise_mm": "--noise-mm", "noise_deg": "--noise-deg", "grid": "--grid",
            "model": "--model", "push_n": "--push-n", "accuracy_mm": "--accuracy-mm",
            "accuracy_deg": "--accuracy-deg", "limit_tolerance_mm": "--limit-tolerance-mm"}


def _named(check, *values):
    """Run a library check (or computation) on option values; a ConfigError keyed by a Python keyword is raised
    again keyed by the option of that keyword, so the one error line names what the user typed."""
    from ..errors import ConfigError

    try:
        return check(*values)
    except ConfigError as exc:
        if exc.key not in _OPTIONS:
            raise
        raise type(exc)(exc.message, source=exc.source, key=_OPTIONS[exc.key]) from None


def run_simulate(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..experiment.virtual_rig import _check_simulation

    robot = _common.load_robot(args)
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    if args.grid < 2:      # before any output folder is made
        raise ConfigError(f"the grid needs at least 2 points per axis, got {args.grid}", key="--grid")
    _named(_check_simulation, args.take_up, args.noise_mm, args.noise_deg, args.model)
    if args.repeats is not None and args.repeats < 2:
        raise ConfigError(f"ISO 9283 repeatability needs at least 2 cycles, got {args.repeats}", key="--repeats")
    for option, value in (("--repeats-out", args.repeats_out), ("--distribution", args.distribution)):
        if value and args.repeats is None:
            raise ConfigError("goes with --repeats N", key=option)
    if args.repeats is not None:
        from ..accuracy.distributions import Distribution

        distribution = Distribution.load(args.distribution)
    if args.grid >= 2:
        _common.check_grid_memory(1, args.grid, "--grid")
        _check_enough_points(robot, args)
    _common.prepare_output(args.out, "--out", (".csv",))
    if args.repeats_out:
        _common.prepare_output(args.repeats_out, "--repeats-out", (".csv",))
    if args.push_n is not None and not args.push_n > 0:
        raise ConfigError(f"must be a force > 0 (N), got {args.push_n:g}", key="--push-n")
    if args.push_n is not None:
        from ..model.plausibility import force_messages, warn

        warn(force_messages({"--push-n": args.push_n}))
    measurements = _named(lambda: experiment.simulate_experiment(
        robot, clearances, math.radians(args.phi_deg), args.grid, take_up=args.take_up, noise_mm=args.noise_mm,
        noise_deg=args.noise_deg, model=args.model, seed=args.seed, push_n=args.push_n))
    path = experiment.write_measurements(args.out, measurements)
    record = {"out": str(path), "points": len(measurements), "rows": len(measurements) * len(experiment.PUSHES),
              "phi_deg": args.phi_deg, "model": args.model, "take_up": args.take_up, "noise_mm": args.noise_mm,
              "noise_deg": args.noise_deg, "seed": args.seed,
              **({"push_n": args.push_n} if args.push_n is not None else {})}
    if args.repeats is not None:
        import numpy as np

        from ..experiment import iso9283

        out = Path(args.repeats_out) if args.repeats_out else path.with_name(f"{path.stem}_repeats.csv")
        repeats = iso9283.simulate_repeats(robot, clearances, measurements.nominal, args.repeats,
                                           distribution=distribution, noise_mm=args.noise_mm,
                                           noise_deg=args.noise_deg, model=args.model,
                                           seed=np.random.default_rng((args.seed, 9283)),
                                           labels=measurements.points)
        iso9283.write_repeats(out, repeats)
        record.update({"repeats_out": str(out), "repeats": args.repeats, "repeat_rows": len(repeats) * args.repeats})
    _common.emit(record, args.format)
    return 0


#: The fewest measured points of a comparison: its spread (ssd) and its regression need three.
MIN_POINTS = 3


def _check_enough_points(robot, args: argparse.Namespace) -> None:
    """Refuse (ConfigError naming --grid) a lattice with fewer than :data:`MIN_POINTS` points inside the
    workspace (away from singularities), naming how many are inside and the smallest --grid that has enough."""
    from ..errors import ConfigError
    from ..experiment.virtual_rig import grid_poses

    phi = math.radians(args.phi_deg)
    inside = len(grid_poses(robot, phi, args.grid))
    if inside >= MIN_POINTS:
        return
    larger = next((n for n in range(args.grid + 1, args.grid + 30) if len(grid_poses(robot, phi, n)) >= MIN_POINTS),
                  None)
    hint = f": use a larger --grid (--grid {larger} has enough)" if larger else ""
    raise ConfigError(f"{inside} of its {args.grid ** 2} points lie inside the workspace at phi = {args.phi_deg:g} deg "
                      f"(away from singularities); the comparison needs at least {MIN_POINTS} (its spread and "
                      f"regression){hint}", key="--grid")


def run_compare(args: argparse.Namespace) -> int:
    from ..errors import ConfigError

    robot = _common.load_robot(args)
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    from ..experiment import _check_accuracy

    _named(_check_accuracy, args.accuracy_mm, args.accuracy_deg, args.limit_tolerance_mm)
    if args.map_grid < 2:
        raise ConfigError(f"the map grid needs at least 2 points per axis, got {args.map_grid}", key="--map-grid")
    if args.push_n is not None and not args.push_n > 0:
        raise ConfigError(f"must be a force > 0 (N), got {args.push_n:g}", key="--push-n")
    repeats = None
    if args.distribution and not args.repeats:
        raise ConfigError("goes with --repeats R.csv (the model's predicted repeatability)", key="--distribution")
    if args.repeats:
        from ..experiment import iso9283
        from ..accuracy.distributions import Distribution

        repeats = iso9283.load_repeats(args.repeats)  # before the long computations
        distribution = Distribution.load(args.distribution)
    if args.out:
        _common.check_grid_memory(1, args.map_grid, "--map-grid")
        _common.prepare_output(args.out, "--out", folder=True)
    comparison = _named(lambda: experiment.compare(
        robot, clearances, args.measurements, accuracy_mm=args.accuracy_mm, accuracy_deg=args.accuracy_deg,
        limit_tolerance_mm=args.limit_tolerance_mm, push_n=args.push_n))
    summary = comparison.summary()
    if repeats is not None:
        summary["iso9283"] = iso9283.compare_repeatability(robot, clearances, repeats, distribution=distribution,
                                                           noise_mm=args.accuracy_mm, noise_deg=args.accuracy_deg)
    if args.out:
        files = experiment_report.write_report(robot, clearances, comparison, args.out, map_grid=args.map_grid)
        summary["files"] = {k: str(p) for k, p in files.items()}
        if repeats is not None:
            import json

            iso_path = Path(args.out) / "iso9283.json"
            iso_path.write_text(json.dumps(_common._plain(summary["iso9283"]), indent=2) + "\n")
            summary["files"]["iso9283"] = str(iso_path)
    if args.format == "json":
        _common.emit(summary, "json")
    elif args.format == "csv":
        _common.emit(summary["pushes"]["pushes"] if args.push_n is not None else summary["points"], "csv")
    else:
        _common.emit(summary["points"], "table")
        sys.stdout.write("\n")
        rows = [{"convention": name, **{q: summary[key][q] for q in _QUANTITIES}}
                for name, key in (("rmsd (measured - max)", "rmsd"),
                                  ("rmsd (measured - 2 max)", "rmsd_width_consistent"),
                                  ("ssd of measured", "ssd"))]
        _common.emit(rows, "table")
        if args.push_n is not None:
            pushes = summary["pushes"]
            sys.stdout.write(f"\npushes of {args.push_n:g} N: measured (reading - nominal) and predicted displacement "
                             f"(mm, deg), range = +-(unloaded legs' spread + 2 accuracy); "
                             f"{100 * pushes['share_inside']:.0f} % inside\n")
            _common.emit([{k: r[k] for k in _PUSH_TABLE} for r in pushes["pushes"]], "table")
        if repeats is not None:
            sys.stdout.write("\nISO 9283 (mm, deg; model: mean [5-95 % of one test])\n")
            _common.emit([{k: r[k] for k in _ISO_TABLE} for r in summary["iso9283"]["points"]], "table")
        if args.out:
            sys.stdout.write(f"\nreport: {summary['files']['report']}\n")
    return 0
