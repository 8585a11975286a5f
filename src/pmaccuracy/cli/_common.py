"""Shared argument types and output formatting of the CLI commands."""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..io.csvio import read_poses_csv  # noqa: F401  (columnar reader; kept importable from here)
from ..errors import ConfigError, PmAccuracyError
from ..model.manipulator import Manipulator
from ..io.resolve import robot_arg
from .._savefig import DEFAULT_DPI, FIGURE_TYPES, check_dpi, figure_format


#: File types of figure options (``--plot``): what matplotlib writes without extra packages
#: (:data:`pmaccuracy._savefig.FIGURE_TYPES`, the table :func:`~pmaccuracy._savefig.save_figure` writes by).
PLOT_TYPES = tuple(FIGURE_TYPES)
#: The folder policy of every output option, as said in each ``--help``.
FOLDER_POLICY = "missing parent folders are created"


def prepare_output(path: str | os.PathLike, option: str = "--out", kinds: Sequence[str] | None = None, *,
                   folder: bool = False) -> Path:
    """Check an output path before anything is computed, and create its missing parent folders.

    The policy of every command: missing folders are created (the path's parents,
    or with ``folder=True`` the path itself, an output folder). Refused with a
    :class:`~pmaccuracy.errors.ConfigError` naming ``option`` and the path: an
    empty path, a suffix not in ``kinds`` (lower-case, e.g. ``(".nc", ".csv")``;
    ``None``: any), a parent that is a file, a folder that cannot be created or
    written, an existing folder where a file is wanted (a ``.zarr`` store is a
    folder) or a file where a folder is wanted, an existing file not writable.
    """
    text = os.fspath(path)
    if not str(text).strip():
        raise ConfigError("empty path", key=option)
    path = Path(text)
    where = str(path)
    suffix = path.suffix.lower()
    if kinds is not None and suffix not in kinds:
        got = f"{path.suffix!r}" if path.suffix else "no file type"
        raise ConfigError(f"unsupported file type {got}: use {', '.join(kinds)}", source=where, key=option)
    target = path if folder else path.parent
    target = target if str(target) else Path(".")
    ancestor = target
    while not ancestor.exists() and ancestor != ancestor.parent:  # the deepest existing folder (or file)
        ancestor = ancestor.parent
    if ancestor.exists() and not ancestor.is_dir():
        raise ConfigError(f"cannot create the folder {target}: {ancestor} is a file", source=where, key=option)
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the folder {target} ({exc.strerror or exc})", source=where,
                          key=option) from None
    if not os.access(target, os.W_OK | os.X_OK) or not _can_create_in(target):
        raise ConfigError(f"the folder {target} is not writable", source=where, key=option)
    if not folder and path.is_dir() and suffix != ".zarr":
        raise ConfigError("is a folder, not a file", source=where, key=option)
    if folder and path.exists() and not path.is_dir():
        raise ConfigError("is a file, not a folder", source=where, key=option)
    if path.exists() and not path.is_dir() and not os.access(path, os.W_OK):
        raise ConfigError("is not writable", source=where, key=option)
    return path


def _can_create_in(folder: Path) -> bool:
    """Whether a file can really be created in ``folder`` (a probe: os.access says yes on /proc, read-only
    mounts, ... for root)."""
    import tempfile

    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def check_grid_memory(layers: int, n: int, option: str = "--grid") -> None:
    """Refuse (ConfigError naming ``option``) a computation over ``layers`` x ``n`` x ``n`` grid points that
    would not fit in the available memory, before anything is computed: the same rule as an in-memory map
    (:func:`pmaccuracy.accuracy.maps.check_fits_in_memory`, four float64 values per point)."""
    from ..accuracy import maps

    need = maps.MEMORY_FACTOR * maps.map_nbytes(layers, n)
    free = maps.available_memory()
    if free is not None and need > free:
        raise ConfigError(f"{n} points per axis ({layers} x {n} x {n}) need about {maps.format_bytes(need)} of "
                          f"memory but only {maps.format_bytes(free)} is available: use a smaller {option}",
                          key=option)


def warn_long_run(seconds: float, what: str, limit: float = 600.0) -> None:
    """A one-line warning printed at once (before computing) when a rough estimate exceeds ``limit`` s."""
    import warnings

    from ..model.plausibility import LongRunWarning

    if seconds > limit:
        hours = seconds / 3600
        span = f"{hours:.1f} h" if hours >= 1.5 else f"{seconds / 60:.0f} min"
        warnings.warn(f"{what}: about {span} of computing (rough estimate); Ctrl-C stops it", LongRunWarning)


def finite_float(text: str) -> float:
    """argparse type: a finite real number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite: {text!r}")
    return value


def angle_deg(text: str) -> float:
    """argparse type of an orientation in degrees: a finite number at most :data:`MAX_POSE_VALUE` in magnitude
    (beyond it the angle keeps no digit and the answer would be an empty workspace or a meaningless pose)."""
    value = finite_float(text)
    if abs(value) > MAX_POSE_VALUE:
        raise argparse.ArgumentTypeError(f"{text!r} deg is beyond {MAX_POSE_VALUE:g} deg in magnitude: not an "
                                         f"orientation (a typing slip?)")
    return value


def check_gap_pct(value: float | None, option: str = "--gap-pct") -> None:
    """Refuse (ConfigError naming ``option``) a gap target outside (0, 100) percent; ``None`` (the default) passes."""
    if value is not None and not 0 < value < 100:
        raise ConfigError(f"must be in (0, 100) percent, got {value:g}", key=option)


def _whole_number(text: str, minimum: int) -> int:
    """A whole number ``>= minimum`` (argparse.ArgumentTypeError otherwise)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"must be at least {minimum}: {text!r}")
    return value


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    return _whole_number(text, 1)


def nonnegative_int(text: str) -> int:
    """argparse type: a whole number >= 0 (seeds of numpy.random.default_rng)."""
    return _whole_number(text, 0)


def check_finite_results(columns: dict[str, np.ndarray], poses: np.ndarray, names: Sequence[str]) -> None:
    """Refuse (PmAccuracyError naming the pose) results that overflowed to +-inf: values far outside any
    physical range (clearances or tolerances of 1e300, a guide block of 1e-300 mm) give no usable bound."""
    for name in names:
        values = np.asarray(columns[name], dtype=float).reshape(-1)
        bad = np.flatnonzero(np.isinf(values))
        if bad.size:
            k = int(bad[0])
            x, y, phi = np.asarray(poses, dtype=float).reshape(-1, 3)[k]
            raise PmAccuracyError(f"{name} overflows at the pose x = {x:g} mm, y = {y:g} mm, phi = "
                                  f"{math.degrees(phi):g} deg ({bad.size} poses): the clearances or tolerances are "
                                  f"far outside any physical range")


def command_line(args: argparse.Namespace) -> str:
    """The command as typed (``pmaccuracy reproduce --out out``), shell-quoted, for a report's footer."""
    import shlex

    return "pmaccuracy " + " ".join(shlex.quote(a) for a in getattr(args, "argv", []))


def add_robot(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="aalborg_3ppr",
                        help="preset name (aalborg_3ppr, symmetric_3ppr, symmetric_3rpr, symmetric_3rrr, "
                             "symmetric_3prr; serial arm for bounds --joints: planar_3r_arm) or path to a robot "
                             "TOML file of any architecture, or an MJCF (.xml), URDF (.urdf) or SDF (.sdf) robot "
                             "file (default: aalborg_3ppr)")


def add_plot(parser: argparse.ArgumentParser, help: str, *, maps: bool = False, units: str = "mm") -> None:
    """``--plot FILE`` (format by its extension: png, pdf, svg, jpg, ...) and ``--dpi``; with ``maps`` also
    the colour limits ``--vmin``/``--vmax`` (in ``units``) and ``--log`` (logarithmic colour scale)."""
    parser.add_argument("--plot", metavar="FILE.png", help=f"{help}; written in the format its extension names "
                        f"({', '.join(t.lstrip('.') for t in PLOT_TYPES)}); missing folders are created")
    parser.add_argument("--dpi", type=finite_float, default=DEFAULT_DPI, metavar="DPI",
                        help=f"dots per inch of a raster --plot (png, jpg, tif, webp; default: {DEFAULT_DPI})")
    if maps:
        parser.add_argument("--vmin", type=finite_float, metavar=units.upper(),
                            help=f"lower end of the colour scale of the {units} panels of --plot, in {units} "
                                 f"(default: the map's smallest value)")
        parser.add_argument("--vmax", type=finite_float, metavar=units.upper(),
                            help=f"upper end of the colour scale of the {units} panels of --plot, in {units} "
                                 f"(default: the map's largest value, or its 95th percentile when a "
                                 f"near-singular edge would take over the scale)")
        parser.add_argument("--log", action="store_true",
                            help="logarithmic colour scale in --plot (for maps spanning decades)")


def check_plot_options(args: argparse.Namespace) -> None:
    """Check ``--plot``'s file type, ``--dpi`` and the colour options (no file system access): a ConfigError
    naming the option."""
    if args.plot:
        figure_format(args.plot, "--plot")
    check_dpi(args.dpi, "--dpi")
    vmin, vmax = getattr(args, "vmin", None), getattr(args, "vmax", None)
    if vmin is not None and vmax is not None and not vmin < vmax:
        raise ConfigError(f"must be below --vmax ({vmax:g}), got {vmin:g}", key="--vmin")
    if getattr(args, "log", False):
        for option, value in (("--vmin", vmin), ("--vmax", vmax)):
            if value is not None and value <= 0:
                raise ConfigError(f"must be > 0 with --log (a logarithmic scale), got {value:g}", key=option)
    if not args.plot:
        if vmin is not None or vmax is not None or getattr(args, "log", False):
            raise ConfigError("colour options go with --plot", key="--vmin" if vmin is not None else
                              "--vmax" if vmax is not None else "--log")


def check_plot(args: argparse.Namespace) -> Path | None:
    """Check ``--plot`` (file type, folder: :func:`prepare_output`), ``--dpi`` and the colour options before
    anything is computed; returns the plot path or None. Each problem is a ConfigError naming its option."""
    check_plot_options(args)
    return prepare_output(Path(args.plot), "--plot", PLOT_TYPES) if args.plot else None


def add_format(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--format", choices=("table", "json", "csv"), default="table",
                        help="output format on stdout (default: table)")


#: The commands that take spatial robots so far (the others refuse them in one line).
SPATIAL_COMMANDS = ("ik", "fk", "workspace", "bounds", "map", "statistics", "synthesize", "reproduce", "template",
                    "load", "preload", "worst")


def load_robot(args: argparse.Namespace) -> Manipulator:
    """The robot of ``--robot``; a spatial robot only for :data:`SPATIAL_COMMANDS` (one line otherwise)."""
    robot = robot_arg(args.robot)
    refuse_spatial(robot, args)
    return robot


def refuse_spatial(robot: Any, args: argparse.Namespace) -> None:
    """One line (PmAccuracyError) when ``robot`` is spatial and the command does not take spatial robots yet."""
    from ..model.spatial import is_spatial

    command = getattr(args, "command", None)
    if is_spatial(robot) and command not in SPATIAL_COMMANDS:
        sub = next((v for k, v in sorted(vars(args).items()) if k.endswith("_command") and isinstance(v, str)), "")
        name = f"{command} {sub}".strip()
        raise PmAccuracyError(f"--robot: {robot.name} is a spatial robot ({robot.architecture}); '{name}' takes "
                              f"planar robots only so far (spatial robots: {', '.join(SPATIAL_COMMANDS)})")


def _plain(value: Any) -> Any:
    """numpy scalars/arrays to JSON-able Python values; NaN becomes null."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in np.asarray(value, dtype=object).tolist()] if isinstance(value, np.ndarray) \
            else [_plain(v) for v in value]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def _flat(record: dict[str, Any]) -> dict[str, Any]:
    """Flatten lists and nested dicts for csv/table: ``s: [1,2,3]`` -> ``s1, s2, s3``."""
    out: dict[str, Any] = {}
    for key, value in record.items():
        if isinstance(value, dict):
            for k2, v2 in _flat(value).items():
                out[f"{key}.{k2}"] = v2
        elif isinstance(value, (list, tuple)):
            for i, v in enumerate(value, start=1):
                out[f"{key}{i}"] = v
        else:
            out[key] = value
    return out


def _cell(value: Any, full: bool = False) -> str:
    """Text of a table cell (6 significant digits) or, with ``full``, of a CSV field (exact round trip)."""
    if value is None:
        return "nan"
    if isinstance(value, float):
        return repr(value) if full else f"{value:.6g}"
    return str(value)


def emit(data: Any, fmt: str, *, records: Sequence[dict[str, Any]] | None = None, stream=None) -> None:
    """Write ``data`` as JSON, or ``records`` (default: ``data`` if it is a list) as CSV or an aligned table."""
    stream = stream or sys.stdout
    data = _plain(data)
    if fmt == "json":
        json.dump(data, stream, indent=2)
        stream.write("\n")
        return
    rows = [_flat(r) for r in (_plain(records) if records is not None else data if isinstance(data, list)
                              else [data])]
    columns: list[str] = []
    for row in rows:
        columns.extend(k for k in row if k not in columns)
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(row.get(k), full=True) for k in columns})
        stream.write(buf.getvalue())
        return
    cells = [[_cell(row.get(k, "")) for k in columns] for row in rows]
    widths = [max([len(c)] + [len(r[j]) for r in cells]) for j, c in enumerate(columns)]
    stream.write("  ".join(c.rjust(w) for c, w in zip(columns, widths)) + "\n")
    for r in cells:
        stream.write("  ".join(v.rjust(w) for v, w in zip(r, widths)) + "\n")


def degrees_as_given(angles_rad: np.ndarray) -> np.ndarray:
    """Degrees of angles (rad) for output: per element the shortest rounding that converts back to the same
    radians (``radians(30)`` prints 30, not 29.999999999999996), so an echoed input reads as it was typed.

    Vectorized :func:`pmaccuracy.model.manipulator.round_trip_degrees`: one pass per number of decimals, over the values
    not yet resolved.
    """
    rad = np.asarray(angles_rad, dtype=float)
    deg = np.degrees(rad)
    out = deg.copy()
    finite = np.isfinite(rad)
    # A rounding to k decimals that converts back to the same radians lies near the value, and it is near a
    # multiple of 10^-k, hence of 10^-K for every K >= k: a value far from every multiple of 10^-K cannot
    # resolve with K decimals or fewer and starts at K + 1 (a file of random 16-digit angles would otherwise
    # take all 16 passes; issue 35). Bounds: both the rounding c and the value convert to the same radians
    # R (radians() is monotone), so |c - deg| <= ulp(R) / (pi/180) <= 2^-52 |deg|, and c is within half an
    # ulp of m 10^-k; the distance to the grid is measured within half an ulp of deg 10^K. Hence, in steps of
    # the grid: |deg| <= 1000, K = 9: at most 3.4e-4 off, measured within 1.2e-4 (threshold 1e-3);
    # |deg| <= 64, K = 12: at most 0.022 off, measured within 0.008 (threshold 0.05).
    start = np.zeros(rad.shape, dtype=np.int8)
    with np.errstate(invalid="ignore"):
        size = np.abs(deg)
        for limit, K, threshold in ((1000.0, 9, 1e-3), (64.0, 12, 0.05)):
            scaled = deg * 10.0 ** K
            far = finite & (size <= limit) & (np.abs(scaled - np.rint(scaled)) >= threshold)
            start[far] = K + 1
    for first in (0, 10, 13):
        todo = np.flatnonzero(finite & (start == first))
        for digits in range(first, 16):
            if todo.size == 0:
                break
            candidate = np.round(deg.flat[todo], digits)
            ok = np.radians(candidate) == rad.flat[todo]
            out.flat[todo[ok]] = candidate[ok]
            todo = todo[~ok]
    return out


def poses_from_args(pose_args: list[list[float]] | None, csv_path: str | None) -> np.ndarray:
    """Poses ``(N, 3)`` [mm, mm, rad] from repeated ``--pose X Y PHI_DEG`` or a CSV ``x,y,phi_deg``."""
    if bool(pose_args) == bool(csv_path):
        raise PmAccuracyError("give poses with --pose X Y PHI_DEG (repeatable) or --poses-csv FILE"
                              + (", not both" if pose_args else ""))
    if pose_args:
        arr = np.array(pose_args, dtype=float)
    else:
        from ..model.plausibility import orientation_messages, warn

        arr = read_poses_csv(csv_path)
        warn(orientation_messages(arr[:, 2], f"{csv_path}: column phi_deg"))
    _check_pose_magnitudes(arr, pose_args, csv_path)
    arr[:, 2] = np.radians(arr[:, 2])
    return arr


#: Largest |x|, |y| (mm) or |phi| (deg) of a pose given on the command line: beyond it the kinematics overflow or
#: lose every digit (1e9 mm is 1000 km; 1e9 deg keeps the angle to 1e-7 deg), so the value is a typing slip.
MAX_POSE_VALUE = 1e9


def _check_pose_magnitudes(arr: np.ndarray, pose_args, csv_path) -> None:
    """Refuse (PmAccuracyError naming --pose and which one, or the CSV file and its data row) a pose value above
    :data:`MAX_POSE_VALUE` in magnitude, instead of answering with overflowed or meaningless joint values."""
    big = np.argwhere(np.abs(arr) > MAX_POSE_VALUE)
    if not len(big):
        return
    k, c = (int(v) for v in big[0])
    column, unit = (("x", "mm"), ("y", "mm"), ("phi_deg", "deg"))[c]
    where = (f"--pose (number {k + 1})" if pose_args else f"{csv_path}: data row {k + 1}, column {column}")
    raise PmAccuracyError(f"{where}: {column} = {arr[k, c]:g} {unit} is beyond {MAX_POSE_VALUE:g} {unit} in magnitude: "
                          f"not a pose of a planar robot (a typing slip?)")


#: The help text of every ``--clearances`` option that has the default rule.
CLEARANCES_HELP = ("clearance preset (3-PPR: case1, case2, all, none; 3-RPR: rpr_typical; 3-RRR: rrr_typical; "
                   "3-PRR: prr_typical; serial arm: arm_typical) or path to a clearance TOML file: the 3-PPR format "
                   "or one listing each leg's joints for any architecture (default: case1 for a 3-PPR, the "
                   "architecture's *_typical preset otherwise, printed on stderr)")


def clearances_or_default(args: argparse.Namespace, robot: Any) -> str | Any:
    """``args.clearances``, or the robot's default (:func:`pmaccuracy.io.resolve.default_clearances`, the one
    rule of every command), said once on stderr as ``clearances: NAME (default)`` (after a successful run, see
    :func:`announce_default_clearances`) and kept in ``args.clearances``. A robot with no default: ConfigError
    naming ``--clearances``."""
    from ..io.resolve import default_clearances

    if getattr(args, "clearances", None) is not None:
        return args.clearances
    try:
        name = default_clearances(robot)
    except ConfigError as exc:
        raise ConfigError(exc.message, key="--clearances") from None
    announce_default_clearances(name, args)
    args.clearances = name
    return name


def announce_default_clearances(text: str, args: argparse.Namespace) -> None:
    """Note ``clearances: TEXT (default)`` in ``args.notes``: :func:`pmaccuracy.cli.main` prints the notes on
    stderr when the command succeeds (before its warnings; a failing run prints only its one error line), not
    with ``--quiet``."""
    note = f"clearances: {text} (default)"
    notes = args.__dict__.setdefault("notes", [])
    if note not in notes:
        notes.append(note)
