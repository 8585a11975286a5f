"""Command-line interface: ``pmaccuracy <command> ...``.

Each command lives in its own module with a ``register(subparsers)`` function.
Every :class:`~pmaccuracy.errors.PmAccuracyError` (bad files, poses outside the
joint ranges, singular poses, negative clearances, ...), every argument error
and every other failure (file system, memory, an unexpected internal error)
ends the program with exit status 2 and one line on stderr,
``pmaccuracy CMD: error: ...``; set ``PMACCURACY_DEBUG=1`` to get the traceback
of the failures that are not the user's input errors. Plausibility warnings
(:mod:`pmaccuracy.model.plausibility`) and other warnings are printed one line each,
``pmaccuracy CMD: warning: ...``, after a successful run (a failing run prints only its error line; a
long-run estimate is printed at once), unless ``--quiet`` (an option of every command). A command run
without ``--clearances`` says which it used, ``clearances: NAME (default)`` (the one rule
:func:`pmaccuracy.io.resolve.default_clearances`), on stderr before those warnings.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
import warnings

from ..errors import PmAccuracyError

#: Commands in help order: name -> (module of ``pmaccuracy.cli`` registering it, one-line help).
#: The help lines let ``pmaccuracy --help`` list every command without importing any command module;
#: ``tests/io/test_csvio.py`` checks that they equal what each module registers.
COMMANDS = {
    "ik": ("kinematics_cmd", "inverse kinematics: actuated and passive joint values of poses (any architecture)"),
    "fk": ("kinematics_cmd", "forward kinematics: every assembly mode for actuator values (any architecture)"),
    "workspace": ("workspace_cmd",
                  "constant-orientation workspace: exact region bounded by segments and arcs (Sec. 3, any "
                  "architecture)"),
    "bounds": ("bounds_cmd", "maximum pose errors due to joint clearances at poses (exact, Eq. 21-22)"),
    "map": ("map_cmd", "error maps over constant-orientation workspaces (NetCDF, Zarr or CSV, optional figure)"),
    "compare-designs": ("designs_cmd", "compare designs of any architectures: workspace areas, mean/max errors, "
                                       "error ratios on the shared region"),
    "reproduce": ("reproduce_cmd",
                  "reproduce the paper: workspace, error maps, paper check, sources, design comparison"),
    "experiment": ("experiment_cmd",
                   "experimental validation: simulate the push protocol, compare measurements with the model"),
    "vision": ("vision_cmd", "vision measurement: calibrate a camera, measure the platform pose"),
    "worst": ("worst_cmd", "certified global worst case of dx, dy, dphi, dp over a region of poses (branch and bound)"),
    "synthesize": ("synthesize_cmd",
                   "tolerance synthesis: largest clearances per joint meeting worst-case targets everywhere in a region"),
    "calibrate": ("calibrate_cmd", "kinematic calibration: plan poses, identify parameters from measurements, "
                                   "compensate, simulate"),
    "statistics": ("statistics_cmd", "distribution of the pose error (Monte Carlo, RSS) beside the worst case: at a pose or percentile maps"),
    "load": ("load_cmd", "pose error under a known platform load: statics, reactions, clearances taken up (any architecture)"),
    "preload": ("preload_cmd", "smallest preload keeping every contact fixed over a box of process wrenches (any architecture)"),
    "import": ("robot_file_cmd", "read a parallel robot from an MJCF, URDF or SDF file (loops closed by "
                                 "constraints) into a robot TOML"),
    "export": ("robot_file_cmd", "write a robot as an MJCF, URDF or SDF file, or its geometry into the file it "
                                 "came from (--like)"),
    "template": ("template_cmd", "print a commented template robot file (or, with --clearances, clearance file) of an "
                                 "architecture"),
}
#: Modules of ``pmaccuracy.cli`` that register commands, in help order.
COMMAND_MODULES = tuple(dict.fromkeys(module for module, _ in COMMANDS.values()))


#: What argparse takes for a negative number rather than an option: also exponent forms (``-1.5e-3``), a
#: trailing dot (``-2.``), ``-inf``/``-nan`` (refused later as not finite). Python < 3.14 knows only ``-12``
#: and ``-1.5``, so ``--pose -1.5e-3 0 0`` failed with "expected 3 arguments".
NEGATIVE_NUMBER = re.compile(r"^-(?:\d[\d_]*\.?[\d_]*|\.\d[\d_]*)(?:[eE][-+]?\d+)?$|^-(?:inf|infinity|nan)$",
                             re.IGNORECASE)


class OneLineParser(argparse.ArgumentParser):
    """argparse, but an argument error is a single line ``pmaccuracy CMD: error: ...`` and exit 2.

    Every parser (the program's, each command's) also takes ``--quiet``, and
    negative numbers in any float notation are values, not options.
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        # argparse (3.11-3.13) reads this attribute in _parse_optional; our options never look like numbers
        self._negative_number_matcher = NEGATIVE_NUMBER
        self.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                          help="no warnings on stderr (values in unlikely units, results beyond the linear "
                               "model, long runs); errors are still printed")

    def parse_known_args(self, args=None, namespace=None):  # the arguments, for error()'s hint
        self._arguments = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())}{self._dash_hint(message)} "
                     f"(see {self.prog} --help)\n")

    def _dash_hint(self, message: str) -> str:
        """``: a value starting with '-' ...`` when an option missed its value because that value starts with
        ``-`` (``--region -35,10,...`` reads as an option): argparse says only "expected one argument"."""
        found = re.match(r"argument (\S+): expected (?:at least )?(?:one|\d+) argument", message)
        if not found:
            return ""
        names = found.group(1).split("/")
        arguments = [str(a) for a in getattr(self, "_arguments", [])]
        for k, item in enumerate(arguments[:-1]):
            value = arguments[k + 1]
            if item in names and value.startswith("-") and value not in self._option_string_actions:
                return f"; a value starting with '-' reads as an option: write {item}={value}"
        return ""


def _requested_command(argv: list[str]) -> str | None:
    """The command named on the command line: the first argument that is not an option."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(argv: list[str] | None = None, *, load_all: bool = False) -> argparse.ArgumentParser:
    """The ``pmaccuracy`` parser; only the module of the requested command is imported.

    Every other command gets a placeholder sub-parser carrying just its help line
    (:data:`COMMANDS`), so ``pmaccuracy --help`` imports no command module and
    ``pmaccuracy bounds ...`` imports only ``bounds_cmd``. ``load_all`` registers
    every module for real (tests, documentation).
    """
    from .. import __version__

    parser = OneLineParser(
        prog="pmaccuracy",
        description="Accuracy of planar parallel manipulators (3-PPR of the paper, 3-RPR, 3-RRR, 3-PRR and any "
                    "chain of R and P joints) with joint clearances: kinematics, workspace, "
                    "exact worst-case pose errors, error maps, experiments and vision measurement. Lengths in mm, "
                    "angles in degrees on the command line.")
    parser.add_argument("--version", action="version", version=f"pmaccuracy {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    sub.required = True
    wanted = _requested_command(sys.argv[1:] if argv is None else argv)
    # A name missing from the table (a typo, or a command a module registers but COMMANDS does not list yet):
    # register everything, so the command still runs and a typo still gets argparse's list of choices.
    load_all = load_all or (wanted is not None and wanted not in COMMANDS)
    registered: set[str] = set()
    for name, (module, help_line) in COMMANDS.items():
        if name in registered:
            continue
        if load_all or (wanted in COMMANDS and COMMANDS[wanted][0] == module):
            before = set(sub.choices)
            importlib.import_module(f".{module}", __name__).register(sub)
            registered |= set(sub.choices) - before
        else:
            sub.add_parser(name, help=help_line, add_help=False)
            registered.add(name)
    return parser


def _one_line(text: object) -> str:
    """A message on one line (newlines and runs of spaces folded)."""
    return " ".join(str(text).split())


def _os_error(exc: OSError) -> str:
    """``FILE: problem`` of a file-system error, or just the problem when it names no file."""
    what = exc.strerror or str(exc) or type(exc).__name__
    names = [str(n) for n in (exc.filename, getattr(exc, "filename2", None)) if n not in (None, "")]
    return ": ".join([" -> ".join(names), what] if names else [f"cannot read or write ({what})"])


def _show_warning(command: str, pending: list[str]):
    """A ``warnings.showwarning`` formatting ``pmaccuracy CMD: warning: ...`` on one line.

    A :class:`~pmaccuracy.model.plausibility.LongRunWarning` is printed at once (before the long computation);
    the others are kept in ``pending`` and printed when the command succeeds: a failing command prints
    only its one error line.
    """
    from ..model.plausibility import LongRunWarning, PlausibilityWarning

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        kind = "" if issubclass(category, PlausibilityWarning) else f" ({category.__name__})"
        text = f"pmaccuracy {command}: warning: {_one_line(message)}{kind}"
        if issubclass(category, LongRunWarning):
            print(text, file=sys.stderr)
        elif text not in pending:
            pending.append(text)
    return show


def _option_warnings(args: argparse.Namespace) -> None:
    """Plausibility of the orientations given as options (``--phi-deg``, ``--pose X Y PHI_DEG``, ``--phi-range-deg``,
    ``--frame X Y PHI_DEG``)."""
    from ..model.plausibility import orientation_messages, warn

    phi = getattr(args, "phi_deg", None)
    if isinstance(phi, (int, float)) and not isinstance(phi, bool):
        phi = [phi]
    if isinstance(phi, list) and all(isinstance(v, (int, float)) for v in phi):
        warn(orientation_messages([v for v in phi if v], "--phi-deg"))
    pose = getattr(args, "pose", None)
    if isinstance(pose, list) and pose:
        rows = pose if isinstance(pose[0], list) else [pose]
        warn(orientation_messages([r[2] for r in rows if len(r) == 3], "--pose phi"))
    phi_range = getattr(args, "phi_range_deg", None)   # calibrate plan --phi-range-deg LO HI
    if isinstance(phi_range, (list, tuple)) and all(isinstance(v, (int, float)) for v in phi_range):
        warn(orientation_messages([v for v in phi_range if v], "--phi-range-deg"))
    frame = getattr(args, "frame", None)   # calibrate identify --frame X Y PHI_DEG
    if isinstance(frame, (list, tuple)) and len(frame) == 3 and isinstance(frame[2], (int, float)):
        warn(orientation_messages([frame[2]] if frame[2] else [], "--frame PHI_DEG"))
    warn(_size_messages(args))


#: Options holding a small length (mm) or angle (deg) of this field, with the largest plausible value:
#: camera noise and accuracy are micrometres, targets and thresholds of pose errors tenths of a mm.
_SMALL_OPTIONS = {"noise_mm": ("--noise-mm", 1.0, "mm"), "accuracy_mm": ("--accuracy-mm", 1.0, "mm"),
                  "limit_tolerance_mm": ("--limit-tolerance-mm", 1.0, "mm"),
                  "noise_deg": ("--noise-deg", 1.0, "deg"), "accuracy_deg": ("--accuracy-deg", 1.0, "deg")}
_ERROR_UNITS = {"dx": "mm", "dy": "mm", "dp": "mm", "dphi_deg": "deg"}


def _size_messages(args: argparse.Namespace) -> list[str]:
    """Plausibility of the small lengths and angles given as options (noise, accuracy, error targets)."""
    out = []
    for dest, (option, limit, unit) in _SMALL_OPTIONS.items():
        value = getattr(args, dest, None)
        if isinstance(value, float) and abs(value) > limit:
            usual = "hundredths of a mm" if unit == "mm" else "hundredths of a degree"
            out.append(f"{option} {value:g} {unit} is above {limit:g} {unit}: measurement noise and accuracy are "
                       f"usually {usual} (wrong unit?)")
    for dest, option in (("target", "--target"), ("threshold", "--threshold")):
        for item in getattr(args, dest, None) or []:
            key, value = item if isinstance(item, tuple) else (str(item).partition("=")[0].strip(),
                                                               str(item).partition("=")[2])
            try:
                number = float(value)
            except ValueError:
                continue
            if key in _ERROR_UNITS and abs(number) > 1.0:
                out.append(f"{option} {key}={number:g} {_ERROR_UNITS[key]} is above 1 {_ERROR_UNITS[key]}: pose "
                           f"errors due to clearances are usually hundredths of a mm or deg (wrong unit?)")
    return out


def _leaf_parser(parser: argparse.ArgumentParser, args: argparse.Namespace) -> argparse.ArgumentParser:
    """The parser of the command (and sub-command) ``args`` ran: ``pmaccuracy experiment simulate``'s."""
    while True:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs or getattr(args, subs[0].dest, None) not in subs[0].choices:
            return parser
        parser = subs[0].choices[getattr(args, subs[0].dest)]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pmaccuracy`` console script; returns the exit status."""
    parser = build_parser(argv)
    args, extras = parser.parse_known_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)   # the command as typed, for reports' footers
    if extras:  # argparse would blame the program ("pmaccuracy: error:"): name the command instead
        _leaf_parser(parser, args).error(f"unrecognized arguments: {' '.join(extras)}")
    debug = os.environ.get("PMACCURACY_DEBUG", "") not in ("", "0")
    # the full command as argparse names it in its own errors: "experiment simulate", "vision pose", "bounds"
    command = " ".join([args.command] + [v for k, v in sorted(vars(args).items())
                                         if k.endswith("_command") and isinstance(v, str)])
    error = f"pmaccuracy {command}: error:"
    pending: list[str] = []
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning(command, pending)
        if getattr(args, "quiet", False):
            warnings.simplefilter("ignore")
        else:
            from ..model.plausibility import PlausibilityWarning

            warnings.simplefilter("always", PlausibilityWarning)
        try:
            _option_warnings(args)
            status = int(args.func(args) or 0)
            if not getattr(args, "quiet", False):   # notes of the run (the default clearances used), then warnings
                pending[:0] = getattr(args, "notes", [])
            if pending:   # after the output, as a terminal shows it, also when stdout is a pipe
                sys.stdout.flush()
            for text in pending:
                print(text, file=sys.stderr)
            return status
        except PmAccuracyError as exc:
            print(f"{error} {_one_line(exc)}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:  # Ctrl-C: one line, no traceback (a .zarr map resumes when run again)
            print(f"pmaccuracy {command}: interrupted", file=sys.stderr)
            return 130
        except BrokenPipeError:  # output piped into e.g. `head`: not an error of ours
            sys.stderr.close()
            return 0
        except MemoryError as exc:
            if debug:
                raise
            detail = f" ({_one_line(exc)})" if str(exc) else ""
            print(f"{error} out of memory{detail}: reduce the sizes given on the command line (--grid, "
                  f"--samples, the number of poses) or write a map as .zarr", file=sys.stderr)
            return 2
        except OSError as exc:
            if debug:
                raise
            print(f"{error} {_one_line(_os_error(exc))}", file=sys.stderr)
            return 2
        except Exception as exc:  # noqa: BLE001 - the last line of defence: still one line, exit 2
            if debug:
                raise
            print(f"{error} internal error ({type(exc).__name__}: {_one_line(exc)}); please report it with the "
                  f"command line (PMACCURACY_DEBUG=1 shows the traceback)", file=sys.stderr)
            return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
