"""Shared fixtures and generators of the pmaccuracy test-suite.

Contents
--------
* ``aalborg``, ``symmetric``: the two presets.
* ``rng``: a seeded numpy generator.
* :func:`random_manipulator` (seeded numpy) and :func:`manipulators` (hypothesis
  strategy): random valid 3-PPR geometries together with a *home* pose that
  lies strictly inside their joint ranges, hence inside the constant-orientation
  workspace at the home orientation. Import them with ``from conftest import ...``.
* :func:`condition_of_a`: an independent (SVD) condition number of A, Eq. 4a.
* :func:`poses_inside`: random poses inside the joint ranges (rejection
  sampling with the inverse kinematics).
* ``bad_robot``: a parametrized fixture writing one malformed robot file per
  case of :data:`BAD_ROBOT_CASES` to ``tmp_path``.
"""

from __future__ import annotations

import copy
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
import tomli_w
from hypothesis import assume, settings
from hypothesis import strategies as st

from pmaccuracy.errors import ConfigError, GeometryError
from pmaccuracy.model.manipulator import Leg, Manipulator
from pmaccuracy.kinematics import inverse_kinematics, jacobians

# The suite mirrors the package's layers (tests/model, tests/accuracy, ...); its independent references live
# in tests/reference. Both folders are importable by plain name from every test module (``import
# error_reference``, ``from conftest import ...``).
_HERE = Path(__file__).resolve().parent
for _folder in (_HERE / "reference", _HERE):
    if str(_folder) not in sys.path:
        sys.path.insert(0, str(_folder))

# Property tests run derandomized and without an example database: CI (a clean clone) and a developer's
# machine see the same examples, so a run's result does not depend on what an earlier run happened to find.
settings.register_profile("pmaccuracy", derandomize=True, database=None)
settings.load_profile("pmaccuracy")

def run_cli(argv, capsys, *, catch: bool = False):
    """``(status, stdout, stderr)`` of ``pmaccuracy ARGV`` run in-process (every item passed through ``str``);
    argparse's ``SystemExit`` counts as a status. With ``catch`` an escaping exception becomes the status
    ``"exception"`` with its traceback appended to stderr (for batteries that must report every case); without
    it the exception propagates to pytest. Imported by the test modules as ``from conftest import run_cli``."""
    import traceback

    from pmaccuracy.cli import main

    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    except BaseException:  # noqa: BLE001 - reported by the caller's assertions
        if not catch:
            raise
        out = capsys.readouterr()
        return "exception", out.out, out.err + traceback.format_exc()
    out = capsys.readouterr()
    return status, out.out, out.err


#: Random geometries keep |sin(gamma + theta)| above this (guide and bearing well apart).
MIN_SINE = 0.2
#: Random home poses are kept further than this from the parallel singularity (condition number of A).
MAX_HOME_CONDITION = 50.0


def condition_of_a(robot: Manipulator, poses: np.ndarray) -> np.ndarray:
    """2-norm condition number (SVD) of A (Eq. 4a) with its third column divided by the mean r.

    Computed here rather than with ``kinematics.singularity`` so that the random
    geometries do not depend on the code under test (it also catches a rank-1 A,
    e.g. three parallel bearings, which is singular at every pose).
    """
    A, _ = jacobians(robot, poses)
    A = A / np.array([1.0, 1.0, float(np.mean(robot.r))])
    return np.linalg.cond(A)


# ----------------------------------------------------------------------------------- presets, rng
@pytest.fixture(scope="session")
def aalborg() -> Manipulator:
    return Manipulator.preset("aalborg_3ppr")


@pytest.fixture(scope="session")
def symmetric() -> Manipulator:
    return Manipulator.preset("symmetric_3ppr")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20120411)


# ----------------------------------------------------------------------------------- random robots
@dataclass(frozen=True)
class RandomRobot:
    """A random manipulator and a pose ``home`` (mm, mm, rad) strictly inside its joint ranges."""

    robot: Manipulator
    home: np.ndarray


def build_manipulator(params: dict[str, np.ndarray], home: np.ndarray,
                      s_margins: np.ndarray, l_margins: np.ndarray, name: str = "random") -> RandomRobot:
    """Assemble a manipulator whose joint ranges surround the joint values of ``home``.

    ``params`` maps a, alpha, beta, gamma, theta, d, r, psi to arrays ``(3,)`` (mm, rad);
    ``s_margins`` and ``l_margins`` ``(3, 2)`` (mm, > 0) are how far each range extends
    below and above the home joint value.
    """
    provisional = Manipulator(legs=tuple(
        Leg(**{k: float(v[i]) for k, v in params.items()}, s_range=(-1.0, 1.0), l_range=(-1.0, 1.0))
        for i in range(3)), name=name)
    ik = inverse_kinematics(provisional, home)
    legs = tuple(
        Leg(**{k: float(v[i]) for k, v in params.items()},
            s_range=(float(ik.s[i] - s_margins[i, 0]), float(ik.s[i] + s_margins[i, 1])),
            l_range=(float(ik.l[i] - l_margins[i, 0]), float(ik.l[i] + l_margins[i, 1])))
        for i in range(3))
    return RandomRobot(Manipulator(legs=legs, name=name), np.asarray(home, dtype=float))


# |gamma + theta| is drawn in [_LO_ANGLE, _HI_ANGLE], so |sin(gamma + theta)| > MIN_SINE.
_LO_ANGLE = float(np.arcsin(MIN_SINE)) + 1e-3
_HI_ANGLE = float(np.pi - np.arcsin(MIN_SINE)) - 1e-3


def random_manipulator(rng: np.random.Generator, name: str = "random") -> RandomRobot:
    """A random valid geometry (seeded numpy version of :func:`manipulators`).

    a in [80, 250] mm, d in [0, 100] mm, r in [10, 60] mm, all angles uniform,
    |sin(gamma + theta)| >= 0.2; home position in [-30, 30]^2 mm, any phi, with
    condition number of A (Eq. 4a) below :data:`MAX_HOME_CONDITION`; joint
    ranges extend 5-40 mm on each side of the home joint values.
    """
    while True:
        gamma = rng.uniform(-np.pi, np.pi, 3)
        gt = rng.choice([-1.0, 1.0], 3) * rng.uniform(_LO_ANGLE, _HI_ANGLE, 3)
        params = {
            "a": rng.uniform(80, 250, 3), "alpha": rng.uniform(-np.pi, np.pi, 3),
            "beta": rng.uniform(-np.pi, np.pi, 3), "gamma": gamma, "theta": gt - gamma,
            "d": rng.uniform(0, 100, 3), "r": rng.uniform(10, 60, 3), "psi": rng.uniform(-np.pi, np.pi, 3),
        }
        home = np.array([rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(-np.pi, np.pi)])
        out = build_manipulator(params, home, rng.uniform(5, 40, (3, 2)), rng.uniform(5, 40, (3, 2)), name)
        if condition_of_a(out.robot, home) < MAX_HOME_CONDITION:
            return out


_angle = st.floats(-np.pi, np.pi, allow_nan=False)
_margin = st.floats(5.0, 40.0)


def _triple(elements: st.SearchStrategy[float]) -> st.SearchStrategy[np.ndarray]:
    return st.tuples(elements, elements, elements).map(np.array)


@st.composite
def manipulators(draw: Callable, max_condition: float = MAX_HOME_CONDITION) -> RandomRobot:
    """Hypothesis strategy of :class:`RandomRobot` (same distribution as :func:`random_manipulator`)."""
    gamma = draw(_triple(_angle))
    gt = draw(_triple(st.sampled_from([-1.0, 1.0]))) * draw(_triple(st.floats(_LO_ANGLE, _HI_ANGLE)))
    params = {
        "a": draw(_triple(st.floats(80, 250))), "alpha": draw(_triple(_angle)), "beta": draw(_triple(_angle)),
        "gamma": gamma, "theta": gt - gamma, "d": draw(_triple(st.floats(0, 100))),
        "r": draw(_triple(st.floats(10, 60))), "psi": draw(_triple(_angle)),
    }
    home = np.array([draw(st.floats(-30, 30)), draw(st.floats(-30, 30)), draw(_angle)])
    margins = [np.array([draw(st.tuples(_margin, _margin)) for _ in range(3)]) for _ in range(2)]
    bearing = params["alpha"] + params["beta"] + gt
    # Three parallel bearings are a degenerate architecture (A singular everywhere), refused by Manipulator.
    assume(np.max(np.abs(np.sin(bearing - bearing[0]))) > 1e-3)
    out = build_manipulator(params, home, margins[0], margins[1], name="hypothesis")
    assume(condition_of_a(out.robot, home) < max_condition)
    return out


def poses_inside(robot: Manipulator, home: np.ndarray, rng: np.random.Generator, n: int,
                 spread: float = 20.0, vary_phi: bool = False) -> np.ndarray:
    """Up to ``n`` random poses ``(m, 3)`` within the joint ranges, sampled around ``home``.

    Positions uniform in a square of half-side ``spread`` mm around ``home``
    (phi fixed unless ``vary_phi``: then +-0.3 rad), kept where the inverse
    kinematics (Eq. 2a, 2b) is within the limits. ``home`` is always the first row.
    """
    cand = np.repeat(np.asarray(home, float)[None], 20 * n, axis=0)
    cand[:, :2] += rng.uniform(-spread, spread, (20 * n, 2))
    if vary_phi:
        cand[:, 2] += rng.uniform(-0.3, 0.3, 20 * n)
    ok = inverse_kinematics(robot, cand).within_limits
    return np.vstack([home, cand[ok][: n - 1]])


# ----------------------------------------------------------------------------------- bad robot files
def _preset_dict() -> dict[str, Any]:
    data = Manipulator.preset("aalborg_3ppr").to_dict()
    data["name"] = "broken"
    return data


def _set(leg: int, key: str, value: Any) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        data["legs"][leg][key] = value
    return mutate


def _delete(leg: int, key: str) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        del data["legs"][leg][key]
    return mutate


def _rename(leg: int, old: str, new: str) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        data["legs"][leg][new] = data["legs"][leg].pop(old)
    return mutate


def _legs(count: int) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        data["legs"] = (data["legs"] * 2)[:count]
    return mutate


def _parallel(data: dict) -> None:
    data["legs"][2]["gamma_deg"] = 120.0
    data["legs"][2]["theta_deg"] = 60.0   # gamma + theta = 180 deg: bearing along the guide


def _top(key: str, value: Any) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        data[key] = value
    return mutate


@dataclass(frozen=True)
class BadRobotCase:
    """One malformed robot file: how to break the preset, which key the message must name."""

    id: str
    change: Callable[[dict], None] | str   # mutation of the preset dict, or raw TOML text
    key: str | None                        # substring naming the key (None: only the file)
    error: type[ConfigError] = ConfigError


BAD_ROBOT_CASES = (
    BadRobotCase("malformed-toml", "name = 'x'\n[[legs]\na = 1\n", None),
    BadRobotCase("missing-key", _delete(1, "d"), "legs[2].d"),
    BadRobotCase("missing-legs", "name = 'x'\n", "legs"),
    BadRobotCase("non-numeric", _set(0, "a", "192.34"), "legs[1].a"),
    BadRobotCase("boolean-value", _set(0, "beta_deg", True), "legs[1].beta_deg"),
    BadRobotCase("non-finite-inf", _set(2, "r", float("inf")), "legs[3].r"),
    BadRobotCase("non-finite-nan", _set(1, "psi_deg", float("nan")), "legs[2].psi_deg"),
    BadRobotCase("negative-a", _set(0, "a", -192.34), "legs[1].a"),
    BadRobotCase("negative-d", _set(1, "d", -1.0), "legs[2].d"),
    BadRobotCase("zero-r", _set(0, "r", 0.0), "legs[1].r"),
    BadRobotCase("negative-r", _set(2, "r", -30.0), "legs[3].r"),
    BadRobotCase("empty-s-range", _set(0, "s_range", [10.0, 10.0]), "legs[1].s_range"),
    BadRobotCase("reversed-l-range", _set(1, "l_range", [160.0, 20.0]), "legs[2].l_range"),
    BadRobotCase("range-not-a-pair", _set(2, "s_range", [1.0, 2.0, 3.0]), "legs[3].s_range"),
    BadRobotCase("two-legs", _legs(2), "legs"),
    BadRobotCase("four-legs", _legs(4), "legs"),
    BadRobotCase("unknown-key-alpha", _rename(0, "alpha_deg", "alpha"), "legs[1].alpha"),
    BadRobotCase("unknown-top-key", _top("colour", "red"), "colour"),
    BadRobotCase("wrong-architecture", _top("architecture", "3-RPR"), "architecture"),
    BadRobotCase("bearing-parallel-to-guide", _parallel, "legs[3]", GeometryError),
)


@dataclass(frozen=True)
class BadRobotFile:
    case: BadRobotCase
    path: Path


def write_bad_robot(case: BadRobotCase, folder: Path) -> Path:
    """Write the malformed robot file of ``case`` into ``folder``; returns its path."""
    path = folder / f"robot-{case.id}.toml"
    if isinstance(case.change, str):
        path.write_text(case.change, encoding="utf-8")
    else:
        data = copy.deepcopy(_preset_dict())
        case.change(data)
        path.write_text(tomli_w.dumps(data), encoding="utf-8")
    return path


@pytest.fixture(params=BAD_ROBOT_CASES, ids=[c.id for c in BAD_ROBOT_CASES])
def bad_robot(request: pytest.FixtureRequest, tmp_path: Path) -> BadRobotFile:
    """Each malformed robot file of :data:`BAD_ROBOT_CASES`, written to ``tmp_path``."""
    return BadRobotFile(request.param, write_bad_robot(request.param, tmp_path))


#: Tests that run longest alone (the console examples of the README and the guide, one test per page; the
#: commands and vision pages take 20-35 s each on one core): they start first, so that under ``pytest -n`` the
#: other workers share the rest meanwhile instead of waiting for them at the end.
LONGEST_FIRST = ("tests/test_readme.py::test_documented_examples_run_verbatim",)


def pytest_collection_modifyitems(config, items):
    """Move :data:`LONGEST_FIRST` (with their parameters) to the front of the run (the order of the other tests is
    kept)."""
    first = [it for it in items if any(it.nodeid.split("[", 1)[0].endswith(name.split("tests/", 1)[1])
                                       for name in LONGEST_FIRST)]
    if first:
        items[:] = first + [it for it in items if it not in first]
