"""Property-based fuzzing of every input channel of the command line (issue 12, item 6).

Invariant, for any input: ``main(argv)`` returns 0 with finite numbers on stdout,
or 2 with exactly one error line ``pmaccuracy CMD: error: ...`` on stderr
(besides one-line warnings); never another status, never a traceback, never the
boundary's "internal error" (that would be a bug to fix at its root).

Channels: option values (numbers in every notation, NaN, inf, huge, negative,
junk text, duplicates, bad paths), robot TOML, clearance TOML (3-PPR and
per-joint formats), tolerance TOML, poses CSV, measurement CSV, raw bytes in
place of any file. Files are mutations of valid ones (a key replaced, deleted
or added; a cell or a line changed), so the inputs stay close to what a user
writes. Hypothesis runs derandomized, without a database, with bounded
examples: the whole file takes about 30 s.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import tempfile
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pmaccuracy.cli import main
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.model.manipulator import Manipulator

#: Examples per property (PMACCURACY_FUZZ_EXAMPLES=500 for a long hunt; the default keeps the file near 30 s).
EXAMPLES = int(os.environ.get("PMACCURACY_FUZZ_EXAMPLES", "40"))
FUZZ = settings(derandomize=True, database=None, deadline=None, max_examples=EXAMPLES,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
FEW = settings(FUZZ, max_examples=max(1, EXAMPLES * 3 // 8))

ROBOT = Manipulator.preset("aalborg_3ppr").to_dict()
CLEARANCES = ClearanceSet.load("case2").to_dict()
PER_JOINT = {"name": "rpr", "legs": [{"joints": [{"radial": 0.02}, {"actuator": 0.005, "angular": 0.0005},
                                                 {"radial": 0.02}]} for _ in range(3)]}
TOLERANCES = {"name": "t", "legs": [{"d_mm": 0.05, "gamma_rad": 0.001, "theta_rad": 0.001, "r_mm": 0.05}
                                    for _ in range(3)]}
MEASUREMENT_HEADER = "point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg"
PUSHES = ("+x", "-x", "+y", "-y", "+r", "-r")
WORK = Path(tempfile.mkdtemp(prefix="pmaccuracy-fuzz-"))


# ----------------------------------------------------------------------------------- the invariant
def invoke(argv, capsys):
    """Run the CLI in-process: (status, stdout, stderr); an escaping exception fails the test with its argv."""
    capsys.readouterr()
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    except BaseException as exc:  # noqa: BLE001
        pytest.fail(f"{argv}: {type(exc).__name__} escaped main(): {exc}")
    out = capsys.readouterr()
    return status, out.out, out.err


_NONFINITE = re.compile(r"(?<![A-Za-z_])(nan|-?inf|null|NaN|Infinity)(?![A-Za-z_])")


def check(argv, capsys, *, finite_output: bool = True):
    """The invariant for one command line; returns the status."""
    status, out, err = invoke(argv, capsys)
    words = [a for a in map(str, argv) if not a.startswith("-")]
    command = " ".join(words[:2]) if words[0] in ("experiment", "vision") else words[0]
    assert "Traceback" not in err, (argv, err)
    assert "internal error" not in err, (argv, err)
    # a successful run without --clearances also notes the default it used, "clearances: NAME (default)"
    notes = [line for line in err.splitlines() if re.fullmatch(r"clearances: \S+ \(default\)", line)]
    errors = [line for line in err.splitlines() if not re.match(r"^pmaccuracy [\w -]+: warning: ", line)
              and line not in notes]
    assert len(notes) <= 1 and (not notes or status == 0), (argv, err)
    for line in err.splitlines():
        assert line.startswith(f"pmaccuracy {command}") or line in notes, (argv, err)
    if status == 0:
        assert errors == [], (argv, err)
        if finite_output:
            assert not _NONFINITE.search(out), (argv, out[:500])
    else:
        assert status == 2, (argv, status, err)
        # exactly one line: a failing command prints no warnings, only its error
        assert len(err.splitlines()) == 1 and errors[0].startswith(f"pmaccuracy {command}: error: "), (argv, err)
        assert out == "", (argv, out[:300])
    return status


# ----------------------------------------------------------------------------------- strategies
NUMBER_TEXT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-1e3, 1e3).map(lambda v: f"{v:.3e}"),
    st.integers(-10**30, 10**30).map(str),
    st.sampled_from(["0", "-0", "1e-3", "-1.5e-3", "-2E+4", "-.5", "-2.", "1_000", "0x10", "nan", "-inf", "1e308",
                     "-1e308", "1e-320", "", " ", "abc", "-", "--", "1,5", "½", "٣", "1e", "--pose", "0.5236",
                     "88.9", "90", "-90", "180", "360", "1e9"]),
)
JUNK = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20), st.text(max_size=8),
    st.booleans(), st.lists(st.floats(-1e3, 1e3), max_size=4), st.just({}), st.just([[1, 2], [3]]),
    st.sampled_from([0, -1, 1e6, 1e-9, 1e308, 39, 0.0688, 0.0573, "case1", [1, 2], [-40, 10], [10, -40]]),
)


def _paths(data):
    """Every (container, key) of a nested dict/list, for mutation."""
    out = []
    if isinstance(data, dict):
        for k, v in data.items():
            out.append((data, k))
            out.extend(_paths(v))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out.append((data, i))
            out.extend(_paths(v))
    return out


@st.composite
def mutated(draw, base):
    """``base`` with 1-3 mutations: a value replaced by junk, a key deleted, an unknown key added, a list cut."""
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(data)
        if not paths:
            break
        container, key = draw(st.sampled_from(paths))
        action = draw(st.sampled_from(["replace", "replace", "replace", "delete", "add", "cut"]))
        if action == "replace":
            container[key] = copy.deepcopy(draw(JUNK))  # a fresh object: never a table inside itself
        elif action == "delete":
            del container[key]
        elif action == "add" and isinstance(container, dict):
            container[draw(st.sampled_from(["alpha", "bearing_angle_deg", "x", "joints", "legs", "name"]))] = \
                copy.deepcopy(draw(JUNK))
        elif action == "cut" and isinstance(container[key], list):
            container[key] = container[key][:draw(st.integers(0, 2))]
    return data


def toml_text(data) -> str:
    """TOML of a (mutated) table; what tomli_w cannot write (NaN keys, mixed arrays) becomes a raw line."""
    try:
        return tomli_w.dumps(data)
    except (TypeError, ValueError):
        return f"junk = {json.dumps(str(data))[:200]}\n"


@st.composite
def raw_bytes_file(draw):
    """Bytes that are not what they claim to be: binary, UTF-16, a BOM, truncated TOML, an empty file."""
    return draw(st.one_of(
        st.binary(max_size=64),
        st.sampled_from([b"", b"\xef\xbb\xbf", "x,y,phi_deg\n0,0,0\n".encode("utf-16"), b"[[legs]\n",
                         b"legs = 'abc'\n", b"\x00" * 10, b"[[legs]]\n" * 3 + b"bearing_angle = 1e999\n"])))


def write(name: str, content) -> Path:
    path = WORK / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


CELL = st.one_of(NUMBER_TEXT, st.sampled_from(['"0"', '"1,2"', '"', " 1 ", "1;2", "\t", "x" * 20]))


@st.composite
def poses_csv(draw):
    header = draw(st.sampled_from(["x,y,phi_deg", "\ufeffx,y,phi_deg", "phi_deg,y,x", "x,y,phi_deg,extra", "x,y,phi",
                                   "X,Y,PHI_DEG", "x,y,phi_deg,x", "", "x;y;phi_deg"]))
    n_cols = max(1, header.count(",") + 1)
    rows = draw(st.lists(st.one_of(
        st.lists(st.floats(-30, 30).map(lambda v: f"{v:.4g}"), min_size=n_cols, max_size=n_cols),
        st.lists(CELL, min_size=0, max_size=n_cols + 1)), max_size=4))
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    return newline.join([header] + [",".join(r) for r in rows]) + draw(st.sampled_from(["", newline, newline * 2]))


@st.composite
def measurement_csv(draw):
    header = draw(st.sampled_from([MEASUREMENT_HEADER, "\ufeff" + MEASUREMENT_HEADER,
                                   MEASUREMENT_HEADER.replace("push", "pushes"), "point,x,y"]))
    lines = [header]
    for point in draw(st.lists(st.sampled_from(["A", "B", "1"]), min_size=0, max_size=2, unique=True)):
        x0, y0 = draw(st.floats(-10, 10)), draw(st.floats(-10, 10))
        for push in PUSHES:
            cells = [point, f"{x0:.3f}", f"{y0:.3f}", "0", push, f"{x0 + 0.1:.3f}", f"{y0:.3f}", "0.01"]
            if draw(st.integers(0, 9)) == 0:
                cells[draw(st.integers(0, 7))] = draw(CELL)
            if draw(st.integers(0, 19)) == 0:
                cells = cells[:draw(st.integers(0, 7))]
            lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------- option values
@FUZZ
@given(x=NUMBER_TEXT, y=NUMBER_TEXT, phi=NUMBER_TEXT, command=st.sampled_from(["ik", "bounds"]),
       fmt=st.sampled_from(["table", "json", "csv"]))
def test_pose_options(capsys, x, y, phi, command, fmt):
    check([command, "--pose", x, y, phi, "--format", fmt], capsys)


@FEW
@given(q=st.lists(NUMBER_TEXT, min_size=3, max_size=3), allow=st.booleans())
def test_fk_options(capsys, q, allow):
    check(["fk", "--joints", *q] + (["--allow-outside"] if allow else []), capsys, finite_output=False)


@FEW
@given(phi=NUMBER_TEXT)
def test_workspace_options(capsys, phi):
    # an empty workspace prints null bounds on purpose (documented), so only the status and stderr are checked
    check(["workspace", "--phi-deg", phi, "--format", "json"], capsys, finite_output=False)


@FEW
@given(phis=st.lists(st.sampled_from(["0", "0", "10", "-10", "0.5236", "90", "nan", "1e308", "-2e1"]), min_size=1,
                     max_size=3),
       grid=st.one_of(st.integers(-3, 6), st.just(10**7)).map(str),
       out=st.sampled_from(["m.nc", "m.csv", "m.txt", "", "sub/dir/m.csv", "blocker/m.nc", "folder", "big.zarr"]),
       plot=st.sampled_from([None, "p.png", "p.xyz", "blocker/p.png", "p"]),
       extra=st.sampled_from([[], ["--chunk-size", "0"], ["--workers", "2"], ["--tile", "-1"], ["--quiet"]]))
def test_map_options(capsys, phis, grid, out, plot, extra):
    (WORK / "blocker").write_text("a file, not a folder")
    (WORK / "folder").mkdir(exist_ok=True)
    if out == "big.zarr" and grid != str(10**7):
        out = "m.csv"  # a real Zarr run is slow; the huge one is refused before anything is written
    argv = ["map", *[a for phi in phis for a in ("--phi-deg", phi)], "--grid", grid,
            "--out", (WORK / out) if out else "", *extra]
    if plot:
        argv += ["--plot", WORK / plot]
    check(argv, capsys)


@FEW
@given(seed=NUMBER_TEXT, grid=st.sampled_from(["-1", "0", "1", "2", "3", "abc"]),
       take_up=st.sampled_from(["0", "1", "2", "-1", "nan", "0.5"]),
       out=st.sampled_from(["s.csv", "s.txt", "blocker/s.csv", "new/s.csv", ""]))
def test_experiment_simulate_options(capsys, seed, grid, take_up, out):
    (WORK / "blocker").write_text("a file, not a folder")
    check(["experiment", "simulate", "--seed", seed, "--grid", grid, "--take-up", take_up,
           "--out", (WORK / out) if out else ""], capsys)


# ----------------------------------------------------------------------------------- files
@FUZZ
@given(robot=mutated(ROBOT))
def test_robot_files(capsys, robot):
    path = write("robot.toml", toml_text(robot))
    check(["ik", "--pose", "0", "0", "0", "--robot", path], capsys, finite_output=False)  # NaN: unreachable leg
    check(["workspace", "--robot", path], capsys, finite_output=False)


@FUZZ
@given(clearances=st.one_of(mutated(CLEARANCES), mutated(PER_JOINT)), robot=st.sampled_from(["aalborg_3ppr",
                                                                                              "symmetric_3rpr"]))
def test_clearance_files(capsys, clearances, robot):
    path = write("clearances.toml", toml_text(clearances))
    pose = ["0", "0", "0"] if robot == "aalborg_3ppr" else ["0", "0", "10"]
    check(["bounds", "--robot", robot, "--pose", *pose, "--clearances", path], capsys)


@FEW
@given(tolerances=mutated(TOLERANCES))
def test_tolerance_files(capsys, tolerances):
    path = write("tolerances.toml", toml_text(tolerances))
    check(["bounds", "--pose", "0", "0", "0", "--clearances", "none", "--tolerances", path], capsys)


@FUZZ
@given(text=poses_csv(), command=st.sampled_from(["ik", "bounds"]))
def test_poses_csv(capsys, text, command):
    path = write("poses.csv", text)
    check([command, "--poses-csv", path, "--format", "csv"], capsys, finite_output=command == "bounds")


@FEW
@given(text=measurement_csv())
def test_measurement_csv(capsys, text):
    path = write("measurements.csv", text)
    # one point has no sample standard deviation (NaN, on purpose): only the status and stderr are checked
    check(["experiment", "compare", "--measurements", path, "--format", "csv"], capsys, finite_output=False)


@FEW
@given(content=raw_bytes_file(), channel=st.sampled_from(["--robot", "--clearances", "--tolerances", "--poses-csv"]))
def test_raw_bytes_in_place_of_any_file(capsys, content, channel):
    path = write("raw.bin", content)
    argv = ["bounds", channel, path] + ([] if channel == "--poses-csv" else ["--pose", "0", "0", "0"])
    check(argv, capsys)


ARM = {"architecture": "serial", "name": "arm", "joints": [
    {"name": "shoulder", "type": "R", "length": 300.0, "offset_deg": 0.0, "range": [-170.0, 170.0]},
    {"name": "elbow", "type": "R", "length": 250.0, "offset_deg": 0.0, "range": [-150.0, 150.0]},
    {"name": "slide", "type": "P", "length": 0.0, "offset_deg": 0.0, "range": [0.0, 100.0]}]}
ARM_SOURCES = {"name": "arm", "legs": [{"joints": [{"radial": 0.005, "actuator": 0.0003}, {"radial": 0.005},
                                                   {"actuator": 0.01, "lateral": 0.001}]}]}


@FEW
@given(arm=st.one_of(st.just(ARM), mutated(ARM)), sources=st.one_of(st.just(ARM_SOURCES), mutated(ARM_SOURCES)),
       joints=st.lists(NUMBER_TEXT, min_size=1, max_size=4), details=st.booleans())
def test_serial_arm_files_and_joints(capsys, arm, sources, joints, details):
    robot, clearances = write("arm.toml", toml_text(arm)), write("arm_sources.toml", toml_text(sources))
    check(["bounds", "--robot", robot, "--clearances", clearances, "--joints", *joints, "--format", "json"]
          + (["--details"] if details else []), capsys)


DISTRIBUTION = {"default": {"kind": "truncnormal", "sigma": 0.5}, "radial": "boundary"}
REPEATS_HEADER = "point,x_nom,y_nom,phi_nom_deg,cycle,x,y,phi_deg"


@FEW
@given(distribution=mutated(DISTRIBUTION), samples=st.sampled_from(["1", "2", "50"]))
def test_distribution_files(capsys, distribution, samples):
    path = write("distribution.toml", toml_text(distribution))
    check(["statistics", "--pose", "0", "0", "0", "--distribution", path, "--samples", samples, "--format", "json"],
          capsys, finite_output=False)  # one sample has no standard deviation (null, on purpose)


@FEW
@given(text=st.one_of(measurement_csv().map(lambda t: t.replace("push", "cycle").replace("+x", "1")),
                      poses_csv().map(lambda t: REPEATS_HEADER + "\n" + t)))
def test_repeats_csv(capsys, text):
    path = write("repeats.csv", text)
    measurements = write("m_ok.csv", MEASUREMENT_HEADER + "\n" + "".join(
        f"A,0,0,0,{p},0.1,0,0.01\n" for p in PUSHES))
    check(["experiment", "compare", "--measurements", measurements, "--repeats", path, "--format", "csv"], capsys,
          finite_output=False)


@FEW
@given(region=st.one_of(st.lists(NUMBER_TEXT, min_size=1, max_size=5).map(",".join),
                        st.sampled_from(["workspace", "", "0,1,0,1", "1,0,0,1"])),
       phis=st.lists(st.sampled_from(["0", "-1", "1", "nan", "1e308", "90", "0.5"]), min_size=2, max_size=2),
       gap=st.sampled_from(["0.1", "0", "-1", "100", "50", "1e-300"]))
def test_worst_region_options(capsys, region, phis, gap):
    if region in ("workspace", "0,1,0,1") and gap == "1e-300":
        gap = "50"  # a certified gap that small would take long: the other values are refused or quick
    check(["worst", "--phi-deg", *phis, "--region", region, "--gap-pct", gap, "--grid", "5", "2"], capsys)


def test_file_channels_given_a_folder_or_a_device(capsys):
    for channel in ("--robot", "--clearances", "--tolerances", "--poses-csv"):
        for target in (WORK, os.devnull):
            argv = ["bounds", channel, target] + ([] if channel == "--poses-csv" else ["--pose", "0", "0", "0"])
            check(argv, capsys)


# ----------------------------------------------------------------------------------- the issue's cases, one by one
def _line(err: str, kind: str) -> list[str]:
    return [line for line in err.splitlines() if f": {kind}: " in line]


def error_line(argv, capsys, *needles):
    status, out, err = invoke(argv, capsys)
    assert status == 2 and out == "" and "Traceback" not in err, (argv, status, err)
    (line,) = _line(err, "error")
    for needle in needles:
        assert str(needle) in line, (needle, line)
    return line


def warning_lines(argv, capsys, *needles):
    status, out, err = invoke(argv, capsys)
    assert status == 0, (argv, err)
    lines = _line(err, "warning")
    assert lines, (argv, err)
    for needle in needles:
        assert any(str(needle) in line for line in lines), (needle, lines)
    quiet = invoke([*argv, "--quiet"], capsys)
    assert quiet[0] == 0 and quiet[2] == ""
    return lines


def test_issue_tracebacks_are_one_line_errors(tmp_path, capsys):
    error_line(["map", "--phi-deg", 0, "--phi-deg", 0, "--grid", 11, "--out", tmp_path / "a.nc", "--plot",
                tmp_path / "d.png"], capsys, "--phi-deg", "twice")
    error_line(["map", "--phi-deg", 0, "--phi-deg", 0, "--grid", 11, "--out", tmp_path / "a.nc"], capsys,
               "--phi-deg")
    error_line(["map", "--phi-deg", 0, "--grid", 11, "--out", tmp_path / "a.nc", "--plot", tmp_path / "p.xyz"],
               capsys, "--plot", "p.xyz")
    long_cell = tmp_path / "long.csv"
    long_cell.write_text("x,y,phi_deg\n0,0,0\n1," + "1" * 140_000 + ",0\n")
    error_line(["bounds", "--poses-csv", long_cell], capsys, str(long_cell), "line 3")


def test_issue_long_runs_and_output_folders(tmp_path, capsys):
    error_line(["map", "--phi-deg", 0, "--grid", 10**7, "--out", tmp_path / "m.nc"], capsys, "grid", "NetCDF-3")
    error_line(["map", "--phi-deg", 0, "--grid", 10**7, "--out", tmp_path / "m.csv"], capsys, "grid", "disk")
    error_line(["map", "--phi-deg", 0, "--grid", 10**7, "--out", tmp_path / "m.csv", "--dask"], capsys, "grid",
               "memory")
    error_line(["map", "--phi-deg", 0, "--grid", 10**7, "--out", tmp_path / "m.zarr"], capsys, "grid", "disk")
    blocker = tmp_path / "hostname"
    blocker.write_text("x")
    line = error_line(["map", "--phi-deg", 0, "--grid", 5, "--out", blocker / "m.csv"], capsys, "--out", "is a file")
    assert ": : " not in line
    for argv, made in ((["map", "--phi-deg", 0, "--grid", 5, "--out", tmp_path / "a" / "m.csv"], "a/m.csv"),
                       (["map", "--phi-deg", 0, "--grid", 5, "--out", tmp_path / "b" / "m.nc", "--plot",
                         tmp_path / "c" / "m.png"], "c/m.png"),
                       (["experiment", "simulate", "--grid", 2, "--out", tmp_path / "d" / "s.csv"], "d/s.csv")):
        assert invoke(argv, capsys)[0] == 0 and (tmp_path / made).exists()


def test_issue_bom_poses_csv_accepted(tmp_path, capsys):
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbfx,y,phi_deg\r\n1,2,3\r\n")
    status, out, err = invoke(["ik", "--poses-csv", path, "--format", "json"], capsys)
    assert status == 0, err
    assert [json.loads(out)[0][k] for k in ("x", "y", "phi_deg")] == [1.0, 2.0, 3.0]


def test_issue_unit_mistakes_warn(tmp_path, capsys):
    for key, value, needle in (("bearing_angle", 0.0688, "degrees"), ("bearing_angle", 1e6, "degrees"),
                               ("revolute_radial", 39.0, "um")):
        path = tmp_path / f"{key}{value}.toml"
        path.write_text(f"[[legs]]\n{key} = {value!r}\n[[legs]]\n[[legs]]\n")
        warning_lines(["bounds", "--pose", 0, 0, 0, "--clearances", path], capsys, f"legs[1].{key}", needle)
    tol = tmp_path / "tol.toml"
    tol.write_text("[[legs]]\ntheta_rad = 0.0573\n[[legs]]\n[[legs]]\n")
    warning_lines(["bounds", "--pose", 0, 0, 0, "--clearances", "none", "--tolerances", tol], capsys,
                  "theta_rad", "degrees")
    warning_lines(["ik", "--pose", 10, -5, 0.5236], capsys, "0.5236", "radians")
    warning_lines(["map", "--phi-deg", 0.5236, "--grid", 5, "--out", tmp_path / "m.nc"], capsys, "--phi-deg",
                  "radians")
    warning_lines(["bounds", "--pose", 0, 0, 88.9, "--allow-outside"], capsys, "dphi_max", "first-order")


def test_issue_negative_exponents_and_phi_echo(capsys):
    status, out, err = invoke(["bounds", "--pose", "-1.5e-3", 0, 0, "--format", "json"], capsys)
    assert status == 0 and json.loads(out)[0]["x"] == -1.5e-3, err
    status, out, err = invoke(["ik", "--pose", 1, "-2e-3", 30, "--format", "json"], capsys)
    assert status == 0 and json.loads(out)[0]["y"] == -2e-3 and json.loads(out)[0]["phi_deg"] == 30.0, err
    for command in ("ik", "bounds"):
        status, out, err = invoke([command, "--pose", 0, 0, 30.1, "--format", "csv"], capsys)
        assert status == 0 and out.splitlines()[1].split(",")[2] == "30.1", (command, out)


def test_every_parser_takes_quiet_and_help_states_the_folder_policy():
    from pmaccuracy.cli import build_parser

    parser = build_parser([], load_all=True)
    seen = 0
    stack = [parser]
    while stack:
        p = stack.pop()
        assert any("--quiet" in a.option_strings for a in p._actions), p.prog
        for action in p._actions:
            if hasattr(action, "choices") and isinstance(action.choices, dict):
                stack.extend(action.choices.values())
            if p.prog.startswith("pmaccuracy vision"):
                continue  # the vision commands' options are documented by their own module
            if set(action.option_strings) & {"--out", "--plot", "--repeats-out"}:
                seen += 1
                assert "created" in (action.help or ""), (p.prog, action.option_strings, action.help)
    assert seen >= 10
    assert math.isfinite(seen)
