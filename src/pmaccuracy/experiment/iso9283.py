"""ISO 9283 pose accuracy and pose repeatability from repeated measurements, and what the clearances predict.

ISO 9283 (planar poses)
-----------------------
A commanded pose ``(x_c, y_c, phi_c)`` is approached ``n`` times (cycles) and
the attained poses ``(x_j, y_j, phi_j)``, ``j = 1..n``, are measured. With the
barycentre ``(x_bar, y_bar, phi_bar)`` (means over the cycles)::

    AP_x = x_bar - x_c,  AP_y = y_bar - y_c,  AP_p = sqrt(AP_x^2 + AP_y^2)      pose accuracy
    AP_phi = phi_bar - phi_c
    l_j = sqrt((x_j - x_bar)^2 + (y_j - y_bar)^2),  l_bar = mean l_j
    S_l = sqrt(sum (l_j - l_bar)^2 / (n - 1)),  RP_l = l_bar + 3 S_l              pose repeatability
    S_phi = sqrt(sum (phi_j - phi_bar)^2 / (n - 1)),  RP_phi = +-3 S_phi

(:func:`iso_figures`, vectorized over points; ``n >= 2``). Orientations are
taken relative to the commanded one and wrapped to (-180, 180] deg first.

Repeated-pose file
------------------
A CSV file, one row per attained pose, with exactly the columns::

    point,x_nom,y_nom,phi_nom_deg,cycle,x,y,phi_deg

``point`` a label; ``x_nom, y_nom, phi_nom_deg`` the commanded pose (mm, mm,
deg), the same on every row of a point; ``cycle`` a whole number >= 1, each at
most once per point; ``x, y, phi_deg`` the attained pose (mm, mm, deg). Every
point needs at least two cycles (points may have different numbers).
:func:`load_repeats` refuses anything else with a
:class:`~pmaccuracy.errors.MeasurementFileError` naming the file and the line,
including a reading further than :data:`MAX_DEVIATION_MM` or
:data:`MAX_DEVIATION_DEG` from its commanded pose (wrong units). It is a file of
its own, not a column of the push-protocol measurement file
(:mod:`pmaccuracy.experiment.measurements`): a push loads the clearances on purpose,
whereas ISO 9283 measures the pose the robot settles at.

What the clearance model predicts
---------------------------------
Assumption: between two cycles the joint clearances settle in a new state,
drawn independently from the same law inside their sets (uniform by default,
:mod:`pmaccuracy.accuracy.distributions`); the attained pose is the commanded pose plus
the first-order error of that state, plus independent Gaussian measurement
noise (standard deviations ``noise_mm`` on x and y, ``noise_deg`` on phi).
Nothing else varies (no drift, no thermal effect, no actuator error unless the
clearance file lists one). :func:`predicted_repeatability` simulates ``tests``
ISO tests of ``n`` cycles at each point and reports the mean of their RP_l and
RP_phi and the 5-95 % range of a single test (the spread one measured test can
show). The sets are symmetric, so the predicted AP is 0 at first order.

Units: mm and rad in the arrays; mm and degrees in files and summaries (keys ending in ``_deg``).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._textfile import read_csv
from ..errors import ConfigError, MeasurementFileError, SingularPoseError
from ..io.resolve import robot_arg
from ..accuracy.bounds import max_pose_errors
from ..accuracy.distributions import Distribution
from ..accuracy.distributions import as_sources
from ..accuracy.distributions import error_jacobian, sample_sources
from ..accuracy.distributions import to_displacements, source_terms
from ..accuracy.nonlinear import joint_displaced_pose
from ..kinematics import inverse_kinematics
from ..model.plausibility import check_orientations

#: Header of a repeated-pose CSV file.
REPEAT_COLUMNS = ("point", "x_nom", "y_nom", "phi_nom_deg", "cycle", "x", "y", "phi_deg")
#: An attained pose further than this from its commanded position (mm) is refused as a unit error.
MAX_DEVIATION_MM = 5.0
#: An attained orientation further than this from the commanded one (deg) is refused as a unit error.
MAX_DEVIATION_DEG = 5.0
#: Rows of one point must repeat the commanded pose to within this (mm and deg).
NOMINAL_TOLERANCE = 1e-6
#: Simulated ISO tests per point for the model's prediction.
DEFAULT_TESTS = 2000


def _wrap_rad(a):
    return np.angle(np.exp(1j * np.asarray(a, dtype=float)))


@dataclass(frozen=True, eq=False)
class RepeatedPoses:
    """Attained poses of ``m`` commanded poses over up to ``n`` cycles.

    points : ``(m,)`` str labels;  nominal : ``(m, 3)`` commanded ``[mm, mm, rad]``
    attained : ``(m, n, 3)`` ``[mm, mm, rad]``, NaN where a point has fewer cycles; an orientation is stored as
        ``phi_c + wrap(phi - phi_c)``
    cycles : ``(m, n)`` int cycle numbers (0 where missing);  lines : ``(m, n)`` int file lines (0: not from a file)
    """

    points: np.ndarray
    nominal: np.ndarray
    attained: np.ndarray
    cycles: np.ndarray
    lines: np.ndarray
    source: str = "<memory>"

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def counts(self) -> np.ndarray:
        """Number of cycles of each point ``(m,)``."""
        return np.sum(np.isfinite(self.attained[..., 0]), axis=1)

    @classmethod
    def from_arrays(cls, nominal: np.ndarray, attained: np.ndarray, points=None, source: str = "<memory>"
                    ) -> "RepeatedPoses":
        """From commanded ``(m, 3)`` and attained ``(m, n, 3)`` poses (mm, rad), cycles numbered 1..n."""
        nominal = np.asarray(nominal, dtype=float)
        attained = np.array(attained, dtype=float)
        m, n = attained.shape[:2]
        if nominal.shape != (m, 3) or attained.shape != (m, n, 3):
            raise ConfigError(f"expected nominal (m, 3) and attained (m, n, 3), got {nominal.shape} and "
                              f"{attained.shape}", key="attained")
        attained[..., 2] = nominal[:, None, 2] + _wrap_rad(attained[..., 2] - nominal[:, None, 2])
        points = np.array([str(k + 1) for k in range(m)] if points is None else points, dtype=str)
        cycles = np.where(np.isfinite(attained[..., 0]), np.arange(1, n + 1), 0)
        return cls(points, nominal, attained, cycles, np.zeros((m, n), dtype=int), source)


# ============================================================================ file
def _fail(src: str, message: str, line: int | None = None) -> MeasurementFileError:
    return MeasurementFileError(message, source=src, key=None if line is None else f"line {line}")


#: Largest cycle number of a repeated-pose file (a robot's life is far fewer cycles; beyond, a mistyped cell).
MAX_CYCLE = 10 ** 9


def load_repeats(path: str | Path) -> RepeatedPoses:
    """Read and check a repeated-pose CSV file (format in the module docstring); points in order of first
    appearance, cycles in increasing order.

    Raises :class:`~pmaccuracy.errors.MeasurementFileError` naming the file and the line of the first problem.
    """
    src = str(path)
    lines = read_csv(path, MeasurementFileError)
    header = lines[0][1] if lines else None
    if header is None:
        raise _fail(src, f"empty file: expected the header {','.join(REPEAT_COLUMNS)}", 1)
    if [h.strip() for h in header] != list(REPEAT_COLUMNS):
        raise _fail(src, f"header must be {','.join(REPEAT_COLUMNS)!r}, got {','.join(header)!r}", 1)
    rows = []
    for line, row in lines[1:]:
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(REPEAT_COLUMNS):
            raise _fail(src, f"expected {len(REPEAT_COLUMNS)} values ({','.join(REPEAT_COLUMNS)}), got "
                             f"{len(row)}", line)
        cells = [c.strip() for c in row]
        if not cells[0]:
            raise _fail(src, "empty point label", line)
        values = []
        for i in (1, 2, 3, 5, 6, 7):
            try:
                v = float(cells[i])
            except ValueError:
                raise _fail(src, f"column {REPEAT_COLUMNS[i]}: not a number: {cells[i]!r}", line) from None
            if not math.isfinite(v):
                raise _fail(src, f"column {REPEAT_COLUMNS[i]}: not finite: {cells[i]!r}", line)
            values.append(v)
        try:
            cycle = int(cells[4])
        except ValueError:
            cycle = 0
        if not 1 <= cycle <= MAX_CYCLE:
            raise _fail(src, f"column cycle: must be a whole number from 1 to {MAX_CYCLE}, got {cells[4]!r}", line)
        rows.append((line, cells[0], values[:3], cycle, values[3:]))
    if not rows:
        raise _fail(src, "no readings: the file has a header but no data rows")

    order: dict[str, list] = {}  # label -> [nominal, first line, {cycle: (line, reading)}]
    for line, label, nom, cycle, reading in rows:
        entry = order.setdefault(label, [nom, line, {}])
        ref = entry[0]
        dphi = (nom[2] - ref[2] + 180.0) % 360.0 - 180.0
        if abs(nom[0] - ref[0]) > NOMINAL_TOLERANCE or abs(nom[1] - ref[1]) > NOMINAL_TOLERANCE \
                or abs(dphi) > NOMINAL_TOLERANCE:
            raise _fail(src, f"point {label}: commanded pose ({nom[0]:g}, {nom[1]:g}, {nom[2]:g} deg) differs from "
                             f"({ref[0]:g}, {ref[1]:g}, {ref[2]:g} deg) on line {entry[1]}", line)
        if cycle in entry[2]:
            raise _fail(src, f"point {label}: cycle {cycle} repeated (already on line {entry[2][cycle][0]})", line)
        dpos = math.hypot(reading[0] - nom[0], reading[1] - nom[1])
        dang = abs((reading[2] - nom[2] + 180.0) % 360.0 - 180.0)
        if dpos > MAX_DEVIATION_MM:
            raise _fail(src, f"point {label}, cycle {cycle}: attained position is {dpos:.4g} mm from the commanded "
                             f"one, more than {MAX_DEVIATION_MM:g} mm: wrong units (x, y in mm) or wrong point", line)
        if dang > MAX_DEVIATION_DEG:
            raise _fail(src, f"point {label}, cycle {cycle}: attained orientation is {dang:.4g} deg from the "
                             f"commanded one, more than {MAX_DEVIATION_DEG:g} deg: wrong units (phi_deg and "
                             f"phi_nom_deg in degrees) or wrong point", line)
        entry[2][cycle] = (line, reading)
    for label, (nom, first, cyc) in order.items():
        if len(cyc) < 2:
            raise _fail(src, f"point {label}: {len(cyc)} cycle; ISO 9283 repeatability needs at least 2", first)
    m, n = len(order), max(len(e[2]) for e in order.values())
    nominal = np.zeros((m, 3))
    attained = np.full((m, n, 3), np.nan)
    cycles = np.zeros((m, n), dtype=int)
    lines = np.zeros((m, n), dtype=int)
    for k, (nom, _, cyc) in enumerate(order.values()):
        nominal[k] = [nom[0], nom[1], math.radians(nom[2])]
        for j, c in enumerate(sorted(cyc)):
            line, (x, y, phi_deg) = cyc[c]
            attained[k, j] = [x, y, nominal[k, 2] + math.radians((phi_deg - nom[2] + 180.0) % 360.0 - 180.0)]
            cycles[k, j], lines[k, j] = c, line
    return RepeatedPoses(np.array(list(order), dtype=str), nominal, attained, cycles, lines, src)


def write_repeats(path: str | Path, repeats: RepeatedPoses) -> Path:
    """Write a repeated-pose CSV file (:data:`REPEAT_COLUMNS`, mm and deg; shortest round-trip numbers)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(REPEAT_COLUMNS)
        for k, label in enumerate(repeats.points):
            nom = [repr(float(repeats.nominal[k, 0]) + 0.0), repr(float(repeats.nominal[k, 1]) + 0.0),
                   repr(float(np.round(np.degrees(repeats.nominal[k, 2]), 12)) + 0.0)]
            for j in range(repeats.attained.shape[1]):
                if repeats.cycles[k, j] < 1:
                    continue
                x, y, phi = repeats.attained[k, j]
                writer.writerow([label, *nom, int(repeats.cycles[k, j]), repr(float(x)), repr(float(y)),
                                 repr(float(np.degrees(phi)))])
    return path


# ============================================================================ ISO 9283 figures
@dataclass(frozen=True)
class IsoFigures:
    """ISO 9283 figures of each point (arrays ``(...)``): ``n`` cycles; ``ap_x, ap_y, ap_p`` mm; ``ap_phi`` rad;
    ``l_bar, s_l, rp_l`` mm; ``s_phi, rp_phi`` rad (``RP_phi`` is ``+-rp_phi``)."""

    n: np.ndarray
    ap_x: np.ndarray
    ap_y: np.ndarray
    ap_p: np.ndarray
    ap_phi: np.ndarray
    l_bar: np.ndarray
    s_l: np.ndarray
    rp_l: np.ndarray
    s_phi: np.ndarray
    rp_phi: np.ndarray


def iso_figures(attained: np.ndarray, commanded: np.ndarray) -> IsoFigures:
    """ISO 9283 AP and RP (module docstring) from attained poses ``(..., n, 3)`` and commanded ones ``(..., 3)``
    [mm, mm, rad]; NaN rows (missing cycles) are left out. Points with fewer than two cycles get NaN.

    Example
    -------
    >>> f = iso_figures(np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]]), np.zeros(3))
    >>> float(f.ap_p), float(f.l_bar), float(f.rp_l)
    (0.0, 1.0, 1.0)
    """
    a = np.asarray(attained, dtype=float)
    c = np.asarray(commanded, dtype=float)
    rel = a - c[..., None, :]
    rel[..., 2] = _wrap_rad(rel[..., 2])
    ok = np.isfinite(rel[..., 0])
    n = ok.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        bar = np.nansum(np.where(ok[..., None], rel, 0.0), axis=-2) / n[..., None]
        d = rel - bar[..., None, :]
        l = np.hypot(d[..., 0], d[..., 1])
        l_bar = np.where(ok, l, 0.0).sum(axis=-1) / n
        dof = np.where(n >= 2, n - 1, np.nan)
        s_l = np.sqrt(np.where(ok, (l - l_bar[..., None]) ** 2, 0.0).sum(axis=-1) / dof)
        s_phi = np.sqrt(np.where(ok, d[..., 2] ** 2, 0.0).sum(axis=-1) / dof)
    return IsoFigures(n=n, ap_x=bar[..., 0], ap_y=bar[..., 1], ap_p=np.hypot(bar[..., 0], bar[..., 1]),
                      ap_phi=bar[..., 2], l_bar=l_bar, s_l=s_l, rp_l=l_bar + 3 * s_l, s_phi=s_phi,
                      rp_phi=3 * s_phi)


# ============================================================================ model prediction
@dataclass(frozen=True)
class PredictedRepeatability:
    """The clearance model's ISO 9283 repeatability at ``m`` points for ``n`` cycles (module docstring).

    rp_l, rp_l_lo, rp_l_hi : ``(m,)`` mm, mean over the simulated tests and 5-95 % range of one test
    rp_phi, rp_phi_lo, rp_phi_hi : ``(m,)`` rad, likewise
    rp_l_se, rp_phi_se : ``(m,)`` Monte Carlo standard errors of the means
    """

    rp_l: np.ndarray
    rp_l_lo: np.ndarray
    rp_l_hi: np.ndarray
    rp_l_se: np.ndarray
    rp_phi: np.ndarray
    rp_phi_lo: np.ndarray
    rp_phi_hi: np.ndarray
    rp_phi_se: np.ndarray
    cycles: int
    tests: int


def predicted_repeatability(robot, clearances, nominal: np.ndarray, cycles: int, *, tests: int = DEFAULT_TESTS,
                            distribution=None, noise_mm: float = 0.0, noise_deg: float = 0.0,
                            seed: int | None = 0) -> PredictedRepeatability:
    """RP_l and RP_phi the clearance model predicts at commanded poses ``(m, 3)`` [mm, mm, rad] for ISO tests
    of ``cycles`` cycles: ``tests`` simulated tests per point, each cycle a fresh source state
    (:func:`pmaccuracy.accuracy.distributions.sample_sources`) through the first-order model, plus Gaussian noise."""
    check_orientations(nominal, "nominal", poses=True)

    if int(cycles) != cycles or cycles < 2:
        raise ConfigError(f"ISO 9283 repeatability needs at least 2 cycles, got {cycles}", key="cycles")
    if int(tests) != tests or tests < 2:
        raise ConfigError(f"needs at least 2 simulated tests, got {tests}", key="tests")
    for name, value in (("noise_mm", noise_mm), ("noise_deg", noise_deg)):
        if not (math.isfinite(value) and value >= 0):
            raise ConfigError(f"must be a finite standard deviation >= 0, got {value}", key=name)
    robot = robot_arg(robot)
    sources = as_sources(robot, clearances)
    nominal = np.asarray(nominal, dtype=float).reshape(-1, 3)
    rng = np.random.default_rng(seed)
    J = error_jacobian(robot, sources, nominal)  # (m, 3, K)
    Z = sample_sources(sources, int(tests) * int(cycles), rng, distribution).reshape(int(tests), int(cycles), -1)
    E = np.einsum("pqk,tck->tpcq", J, Z)  # (tests, m, cycles, 3)
    E = E + rng.standard_normal(E.shape) * np.array([noise_mm, noise_mm, math.radians(noise_deg)])
    f = iso_figures(E, np.zeros(3))
    out = {}
    for key, v in (("rp_l", f.rp_l), ("rp_phi", f.rp_phi)):
        out[key] = v.mean(axis=0)
        out[f"{key}_se"] = v.std(axis=0, ddof=1) / math.sqrt(v.shape[0])
        out[f"{key}_lo"], out[f"{key}_hi"] = np.quantile(v, [0.05, 0.95], axis=0)
    return PredictedRepeatability(**out, cycles=int(cycles), tests=int(tests))


def simulate_repeats(robot, clearances, nominal: np.ndarray, cycles: int, *, distribution=None,
                     noise_mm: float = 0.0, noise_deg: float = 0.0, model: str = "exact",
                     seed: int | np.random.Generator | None = 0, labels=None,
                     source: str = "virtual ISO 9283 test") -> RepeatedPoses:
    """A virtual ISO 9283 test: at each commanded pose ``(m, 3)`` [mm, mm, rad], ``cycles`` attained poses, each
    with a fresh random source state inside the sets (:func:`pmaccuracy.accuracy.distributions.sample_sources`): the
    pose the perturbed loops close at (``model="exact"``, :func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`) or
    the first-order one, plus Gaussian noise (``noise_mm`` on x and y, ``noise_deg`` on phi)."""
    check_orientations(nominal, "nominal", poses=True)

    if model not in ("exact", "first_order"):
        raise ConfigError(f"unknown reading model {model!r} (choose from exact, first_order)", key="model")
    if int(cycles) != cycles or cycles < 2:
        raise ConfigError(f"ISO 9283 repeatability needs at least 2 cycles, got {cycles}", key="repeats")
    robot = robot_arg(robot)
    sources = as_sources(robot, clearances)
    nominal = np.asarray(nominal, dtype=float).reshape(-1, 3)
    m = nominal.shape[0]
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    Z = sample_sources(sources, m * int(cycles), rng, distribution).reshape(m, int(cycles), -1)
    poses = np.broadcast_to(nominal[:, None, :], (m, int(cycles), 3)).copy()
    if model == "first_order":
        attained = poses + np.einsum("pqk,pck->pcq", error_jacobian(robot, sources, nominal), Z)
    else:

        attained = joint_displaced_pose(robot, poses, to_displacements(source_terms(sources), Z))
    attained = attained + rng.standard_normal(attained.shape) * np.array([noise_mm, noise_mm,
                                                                          math.radians(noise_deg)])
    return RepeatedPoses.from_arrays(nominal, attained, labels, source)


# ============================================================================ comparison
def compare_repeatability(robot, clearances, repeats: RepeatedPoses | str | Path, *, distribution=None,
                          noise_mm: float = 0.0, noise_deg: float = 0.0, tests: int = DEFAULT_TESTS,
                          seed: int | None = 0) -> dict[str, Any]:
    """Measured ISO 9283 AP/RP of a repeated-pose file beside the clearance model's predicted RP, per point.

    The prediction uses each point's number of cycles. Returns a JSON-ready dict: ``source, assumption,
    distribution, noise_mm, noise_deg, tests`` and ``points``: per point ``point, x_nom, y_nom, phi_nom_deg,
    n, ap_x, ap_y, ap_p`` (mm), ``ap_phi_deg, l_bar, s_l, rp_l`` (mm), ``s_phi_deg, rp_phi_deg`` (deg), and the
    model's ``rp_l_model, rp_l_model_lo, rp_l_model_hi`` (mm), ``rp_phi_model_deg, rp_phi_model_lo_deg,
    rp_phi_model_hi_deg`` (deg).
    """
    if isinstance(repeats, RepeatedPoses):   # a file's orientations are degrees, checked by its reader
        check_orientations(repeats.nominal, "repeats.nominal", poses=True)

    robot = robot_arg(robot)
    if not isinstance(repeats, RepeatedPoses):
        repeats = load_repeats(repeats)
    ik = inverse_kinematics(robot, repeats.nominal, 0.005)
    bad = np.flatnonzero(~np.asarray(ik.within_limits))
    if bad.size:
        k = int(bad[0])
        raise MeasurementFileError(f"point {repeats.points[k]}: the commanded pose is outside the joint ranges",
                                   source=repeats.source, key=f"line {int(repeats.lines[k][repeats.lines[k] > 0].min())}"
                                   if repeats.lines[k].max() else None)

    try:  # a commanded pose at or near a singularity has no model: refused, naming the point
        max_pose_errors(robot, as_sources(robot, clearances), repeats.nominal, allow_outside=True)
    except SingularPoseError as exc:
        raise SingularPoseError(f"{repeats.source}: commanded poses: {exc}") from None
    distribution = Distribution.load(distribution)
    measured = iso_figures(repeats.attained, repeats.nominal)
    counts = repeats.counts
    pred = {}
    for n in sorted(set(counts.tolist())):
        idx = np.flatnonzero(counts == n)
        pred[n] = (idx, predicted_repeatability(robot, clearances, repeats.nominal[idx], n, tests=tests,
                                                distribution=distribution, noise_mm=noise_mm, noise_deg=noise_deg,
                                                seed=seed))
    deg = math.degrees
    rows = []
    for k in range(len(repeats)):
        n = int(counts[k])
        idx, p = pred[n]
        j = int(np.flatnonzero(idx == k)[0])
        rows.append({"point": str(repeats.points[k]), "x_nom": float(repeats.nominal[k, 0]) + 0.0,
                     "y_nom": float(repeats.nominal[k, 1]) + 0.0,
                     "phi_nom_deg": float(np.round(np.degrees(repeats.nominal[k, 2]), 12)), "n": n,
                     "ap_x": float(measured.ap_x[k]), "ap_y": float(measured.ap_y[k]), "ap_p": float(measured.ap_p[k]),
                     "ap_phi_deg": deg(measured.ap_phi[k]), "l_bar": float(measured.l_bar[k]),
                     "s_l": float(measured.s_l[k]), "rp_l": float(measured.rp_l[k]),
                     "s_phi_deg": deg(measured.s_phi[k]), "rp_phi_deg": deg(measured.rp_phi[k]),
                     "rp_l_model": float(p.rp_l[j]), "rp_l_model_lo": float(p.rp_l_lo[j]),
                     "rp_l_model_hi": float(p.rp_l_hi[j]), "rp_phi_model_deg": deg(p.rp_phi[j]),
                     "rp_phi_model_lo_deg": deg(p.rp_phi_lo[j]), "rp_phi_model_hi_deg": deg(p.rp_phi_hi[j])})
    inside = [r["rp_l_model_lo"] <= r["rp_l"] <= r["rp_l_model_hi"] for r in rows]
    inside_phi = [r["rp_phi_model_lo_deg"] <= r["rp_phi_deg"] <= r["rp_phi_model_hi_deg"] for r in rows]
    return {"source": repeats.source, "robot": robot.name, "clearances": str(getattr(clearances, "name", clearances)),
            "assumption": "each cycle a fresh, independent state of every clearance inside its set (law below), "
                          "first-order pose error, plus Gaussian noise of sd noise_mm (x, y) and noise_deg (phi); "
                          "model RP: mean over simulated ISO tests with the same number of cycles, _lo/_hi the "
                          "5-95 % range of one test",
            "distribution": distribution.describe(), "noise_mm": float(noise_mm), "noise_deg": float(noise_deg),
            "tests": int(tests), "seed": seed,
            "share_rp_l_in_model_range": float(np.mean(inside)),
            "share_rp_phi_in_model_range": float(np.mean(inside_phi)), "points": rows}
