"""Issue 34, item 3: property-based tests of every file reader.

Arbitrary bytes and mutated valid files (flipped bytes, truncation, inserted bytes, a latin-1 byte, a cell longer
than the csv field limit, one number replaced by an odd token) never raise anything but the library's own error
(a :class:`~pmaccuracy.errors.PmAccuracyError`) whose message names the file; a file the reader accepts is fine
too. Warnings (values in unlikely units) are allowed. The wrench set of the load commands is not a file: its
centre and half-widths are fuzzed instead, and must be refused by name (``wrench_set``).
"""

from __future__ import annotations

import json
import re
import tempfile
import warnings
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pmaccuracy.accuracy.bounds import load_tolerances
from pmaccuracy.accuracy.calibration.data import read_calibration_csv, write_calibration_csv
from pmaccuracy.accuracy.calibration.identify import identification_to_dict
from pmaccuracy.accuracy.calibration.parameters import error_parameters
from pmaccuracy.accuracy.calibration.records import read_identification
from pmaccuracy.accuracy.calibration.simulate import load_parameter_table, simulate_calibration
from pmaccuracy.accuracy.loads import wrench_set_errors
from pmaccuracy.accuracy.regions import load_polygon
from pmaccuracy.errors import PmAccuracyError
from pmaccuracy.experiment.iso9283 import load_repeats
from pmaccuracy.experiment.measurements import load_measurements
from pmaccuracy.io.resolve import load_clearances, robot_arg
from pmaccuracy.model.manipulator import Manipulator

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
DATA = Path(__file__).resolve().parents[1] / "data"
#: Tokens that replace one number of a valid file: odd values, wrong types, empty cells.
TOKENS = ["nan", "inf", "-inf", "1e400", "-1e400", "1e-400", "-0", "0", "-5", "1e9", "\"x\"", "[]", "{}", "true", "",
          "1,2", "0x10", "\u00e9", "99999999999999999999999999", "9" * 400]
NUMBER = re.compile(rb"-?\d+(\.\d+)?([eE][-+]?\d+)?")


def _preset(folder: str, name: str) -> bytes:
    return (resources.files("pmaccuracy") / "data" / folder / f"{name}.toml").read_bytes()


@st.composite
def mutated(draw, base: bytes) -> bytes:
    """``base`` changed in one of the ways of the module docstring, or arbitrary bytes."""
    how = draw(st.sampled_from(["bytes", "flip", "truncate", "insert", "latin1", "huge", "token", "token"]))
    if how == "bytes":
        return draw(st.binary(max_size=600))
    n = len(base)
    at = draw(st.integers(0, n))
    if how == "flip":
        out = bytearray(base)
        for _ in range(draw(st.integers(1, 4))):
            if out:
                out[draw(st.integers(0, len(out) - 1))] = draw(st.integers(0, 255))
        return bytes(out)
    if how == "truncate":
        return base[:at]
    if how == "insert":
        return base[:at] + draw(st.binary(min_size=1, max_size=20)) + base[at:]
    if how == "latin1":
        return base[:at] + "\u00e9".encode("latin-1") + base[at:]
    if how == "huge":
        return base[:at] + b"a" * 131_073 + base[at:]
    numbers = list(NUMBER.finditer(base))
    if not numbers:
        return base
    m = numbers[draw(st.integers(0, len(numbers) - 1))]
    return base[:m.start()] + draw(st.sampled_from(TOKENS)).encode() + base[m.end():]


@pytest.fixture(scope="module")
def folder():
    with tempfile.TemporaryDirectory() as name:
        yield Path(name)


def check(read, path: Path, content: bytes) -> None:
    """``read(path)`` after writing ``content``: accepted, or a PmAccuracyError naming the file."""
    path.write_bytes(content)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            read(path)
        except PmAccuracyError as exc:
            assert path.name in str(exc), str(exc)


@pytest.fixture(scope="module")
def calibration_files(folder):
    """A valid calibration CSV (with sigmas and a comment column) and an identification JSON."""
    pv = error_parameters(Manipulator.preset("aalborg_3ppr"))
    ex = simulate_calibration(pv, 8, seed=1)
    data = folder / "valid_data.csv"
    write_calibration_csv(pv.robot, ex.data.commands, ex.data.poses, data, sigmas=ex.data.sigmas)
    lines = data.read_text().splitlines()
    csv_text = "\n".join([lines[0] + ",note"] + [line + ",ok" for line in lines[1:6]]) + "\n"
    record = json.dumps(identification_to_dict(ex.identification), indent=1)
    return pv, csv_text.encode(), record.encode()


@FUZZ
@given(data=st.data())
def test_robot_toml(folder, data):
    base = _preset("robots", data.draw(st.sampled_from(["aalborg_3ppr", "symmetric_3rrr", "symmetric_3prr"])))
    check(robot_arg, folder / "robot.toml", data.draw(mutated(base)))


@FUZZ
@given(data=st.data())
def test_clearance_toml(folder, data):
    robot, preset = data.draw(st.sampled_from([("aalborg_3ppr", "case2"), ("symmetric_3rrr", "rrr_typical"),
                                               ("symmetric_3rpr", "rpr_tolerances")]))
    check(lambda p: load_clearances(str(p), robot), folder / "clearances.toml",
          data.draw(mutated(_preset("clearances", preset))))


@FUZZ
@given(data=st.data())
def test_tolerance_toml(folder, data):
    base = _preset("variations", data.draw(st.sampled_from(["aalborg_table2", "example_tolerances"])))
    check(lambda p: load_tolerances(str(p)), folder / "tolerances.toml", data.draw(mutated(base)))


@FUZZ
@given(data=st.data())
def test_errors_toml(folder, data):
    pv = error_parameters(robot_arg("symmetric_3rrr"))
    base = b'"leg1.base.x" = 0.2\nleg2.actuator.offset = 0.05\nleg3.actuator.gain = 5e-4\n[frame]\nphi = 0.01\n'
    kind = data.draw(st.sampled_from(["errors", "tolerances"]))
    check(lambda p: load_parameter_table(str(p), pv, kind), folder / "errors.toml", data.draw(mutated(base)))


@FUZZ
@given(data=st.data())
def test_calibration_csv(folder, calibration_files, data):
    pv, base, _ = calibration_files
    check(lambda p: read_calibration_csv(p, pv), folder / "calibration.csv", data.draw(mutated(base)))


@FUZZ
@given(data=st.data())
def test_identification_json(folder, calibration_files, data):
    _, _, base = calibration_files
    check(read_identification, folder / "identification.json", data.draw(mutated(base)))


@FUZZ
@given(data=st.data())
def test_measurement_csv(folder, data):
    base = (DATA / "hand_measurements.csv").read_bytes()
    check(load_measurements, folder / "measurements.csv", data.draw(mutated(base)))


@FUZZ
@given(data=st.data())
def test_repeats_csv(folder, data):
    base = (b"point,x_nom,y_nom,phi_nom_deg,cycle,x,y,phi_deg\nA,0,0,0,1,0.01,0.02,0.001\n"
            b"A,0,0,0,2,0.011,0.019,0.002\nB,10,5,0,1,10.01,5.02,0.001\nB,10,5,0,2,10.0,5.0,0.0\n")
    check(load_repeats, folder / "repeats.csv", data.draw(mutated(base)))


@FUZZ
@given(data=st.data())
def test_polygon_files(folder, data):
    if data.draw(st.booleans()):
        path, base = folder / "polygon.csv", b"x,y\n0,0\n40,0\n40,30\n0,30\n"
    else:
        path, base = folder / "polygon.toml", b"vertices = [[0, 0], [40, 0], [40, 30], [0, 30]]\n"
    check(load_polygon, path, data.draw(mutated(base)))


VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5), st.none(),
                   st.booleans())


@settings(max_examples=60, deadline=None)
@given(center=st.one_of(st.lists(VALUES, max_size=5), VALUES), half=st.one_of(st.lists(VALUES, max_size=5), VALUES))
def test_wrench_set(center, half):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            wrench_set_errors("symmetric_3rpr", "rpr_typical", [0.0, 0.0, 0.0], center, half)
        except PmAccuracyError as exc:
            assert "wrench_set" in str(exc) or "wrench" in str(exc), str(exc)


def test_mutations_reach_the_readers_checks(folder, calibration_files):
    """The valid bases are accepted as they are (so the mutations start from files the readers take)."""
    pv, csv_bytes, json_bytes = calibration_files
    (folder / "ok.csv").write_bytes(csv_bytes)
    (folder / "ok.json").write_bytes(json_bytes)
    assert len(read_calibration_csv(folder / "ok.csv", pv)) == 5
    assert read_identification(folder / "ok.json").n_points >= 6
    assert len(load_measurements(DATA / "hand_measurements.csv")) >= 1
    assert np.isfinite(wrench_set_errors("symmetric_3rpr", "rpr_typical", [0.0, 0.0, 0.0], [1, 0, 0], [1, 1, 10])
                       .upper).all()


@pytest.mark.parametrize("name", ["aalborg_3ppr", "symmetric_3rrr", "symmetric_3prr", "symmetric_3rpr"])
def test_robot_toml_every_number_replaced_by_a_huge_integer(folder, name):
    """Each number of a preset robot file in turn replaced by a 400-digit integer (beyond any float): the
    library's error naming the file, never an OverflowError (found by the fuzzing above in a radians check)."""
    base = _preset("robots", name)
    for m in NUMBER.finditer(base):
        check(robot_arg, folder / "huge.toml", base[:m.start()] + b"9" * 400 + base[m.end():])
