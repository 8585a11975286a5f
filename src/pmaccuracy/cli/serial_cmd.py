"""``pmaccuracy bounds`` for planar serial arms (robot files with ``architecture = "serial"``).

``bounds_cmd.run`` hands a serial robot over to :func:`run` before its
parallel-robot path; the options are those of ``bounds``, with joint values
``--joints Q1 Q2 ...`` (deg for R, mm for P, repeatable) instead of poses.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ..errors import PmAccuracyError, PoseError


def is_serial_robot(spec) -> bool:
    """True when ``--robot`` names a serial arm (preset or file with ``architecture = "serial"``)."""
    from ..model.serial import is_serial_spec

    return is_serial_spec(spec)


def refuse_joints(args: argparse.Namespace) -> None:
    """``--joints`` with a parallel robot: one clear line (exit 2)."""
    if getattr(args, "joints", None):
        raise PmAccuracyError(f"--joints takes a serial arm (architecture = \"serial\", e.g. planar_3r_arm); "
                              f"{args.robot} is a parallel robot: give poses with --pose X Y PHI_DEG or --poses-csv")


def _joint_values(arm, joints: list[list[float]] | None, *, allow_outside: bool = False) -> np.ndarray:
    """Configurations ``(N, n)`` in rad / mm from repeated ``--joints`` (deg for R, mm for P)."""
    units = " ".join(f"Q{k}_{j.unit.upper()}" for k, j in enumerate(arm.joints, start=1))
    if not joints:
        raise PmAccuracyError(f"{arm.name} is a serial arm: give its joint values with --joints {units} "
                              "(repeatable)")
    for i, values in enumerate(joints, start=1):
        if len(values) != arm.n:
            raise PmAccuracyError(f"--joints (occurrence {i}): {arm.name} has {arm.n} joints ({arm.kinds}), got "
                                  f"{len(values)} values; expected --joints {units}")
    from ._common import MAX_POSE_VALUE

    given = np.array(joints, dtype=float)
    big = np.argwhere(np.abs(given) > MAX_POSE_VALUE)
    if len(big):    # answered before with meaningless errors at an angle of 1e300 deg (with --allow-outside)
        i, k = (int(v) for v in big[0])
        raise PmAccuracyError(f"--joints (occurrence {i + 1}): Q{k + 1} = {given[i, k]:g} is beyond "
                              f"{MAX_POSE_VALUE:g} (deg or mm) in magnitude: not a joint value (a typing slip?)")
    q = arm.joints_from_cli(given)
    try:    # "configuration k" is the k-th --joints: the line names the option
        arm.check_joints(q, allow_outside=allow_outside)
    except PoseError as exc:
        raise type(exc)(f"--joints: {exc}") from None
    return q


def _named(key: str, value: np.ndarray):
    """A source's worst-case value for output: a scalar (mm or rad, as in the clearance file), the guide's
    ``{sigma_mm, tau_rad}`` or a disk's translation ``{dx_mm, dy_mm}``."""
    if np.ndim(value) == 0:
        return float(value)
    names = ("sigma_mm", "tau_rad") if key.endswith(".lateral") else ("dx_mm", "dy_mm")
    return dict(zip(names, (float(v) for v in value)))


def run(args: argparse.Namespace) -> int:
    """Exact worst-case end-effector errors of a serial arm at ``--joints`` configurations."""
    from ..model.serial import SerialArm, load_serial_sources, max_serial_errors

    for option, given in (("--pose", args.pose), ("--poses-csv", args.poses_csv)):
        if given:
            raise PmAccuracyError(f"{option} takes a parallel robot; {args.robot} is a serial arm: give joint values "
                                  "with --joints Q1 Q2 ... (deg for R, mm for P)")
    if args.tolerances:
        raise PmAccuracyError("--tolerances takes the 3-PPR format; for a serial arm put per-joint tolerances "
                              "(position, direction, length) in the --clearances file")
    if args.method != "exact":
        raise PmAccuracyError("--method slsqp is for parallel robots; a serial arm's bounds are exact")
    from . import _common

    arm = SerialArm.load(args.robot)
    q = _joint_values(arm, args.joints, allow_outside=args.allow_outside)
    sources = load_serial_sources(_common.clearances_or_default(args, arm), arm)
    result = max_serial_errors(arm, sources, q, allow_outside=args.allow_outside, details=args.details)
    columns = result.columns()
    if not args.details:
        from ..io.csvio import format_columns

        format_columns(columns, args.format, sys.stdout)
        return 0
    shown = np.array(args.joints, dtype=float)  # as given: deg for R, mm for P
    records = []
    for i in range(len(q)):
        rec = {name: float(values[i]) for name, values in columns.items()}
        rec["joints"] = {f"q{k}_{j.unit}": float(shown[i, k - 1]) for k, j in enumerate(arm.joints, start=1)}
        rec["worst"] = {quantity: {key: _named(key, np.asarray(v)[i]) for key, v in values.items()}
                        for quantity, values in result.worst.items()}
        records.append(rec)
    _common.emit(records, args.format)
    return 0
