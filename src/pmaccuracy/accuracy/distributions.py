"""Statistics of the pose error beside its worst case: clearances distributed inside their sets.

The worst case (:func:`pmaccuracy.accuracy.bounds.max_pose_errors`) answers "how far can
the platform be off"; this module answers "how far is it off, typically", when
every error source takes a random value inside its set, independently of the
others and the same law at every repetition.

Sets and laws
-------------
Each source of :mod:`pmaccuracy.model.sources` (per joint, any architecture; the
3-PPR clearance format is converted with
:meth:`~pmaccuracy.model.sources.ErrorSources.from_clearance_set`) has a set of
half-width ``eps`` and one of the laws :data:`LAWS`:

================  ==========================  ==========================================================
set               variables                   laws (``s = sigma eps``, ``sigma`` a fraction of ``eps``)
================  ==========================  ==========================================================
interval          ``d in [-eps, eps]``         uniform; truncnormal ``N(0, s^2)`` cut at ``+-eps``;
(``angular``,                                  boundary ``d = +-eps`` (equal odds)
``direction``,
``actuator``,
``length``)
disk              ``delta = r (cos a, sin a)`` ``a`` uniform; uniform by area ``r = eps sqrt(U)``;
(``radial``,      ``r <= eps``                 truncnormal: isotropic ``N(0, s^2 I)`` cut at ``r = eps``
``position``)                                  (``r = s sqrt(-2 ln(1 - U (1 - exp(-eps^2 / 2 s^2))))``);
                                               boundary ``r = eps`` (a clearance loaded on its edge)
rhombus           ``sigma = eps (u - v) / 2``  ``u, v`` uniform in ``[-1, 1]`` (uniform rhombus); each a
(``lateral``,     ``tau = eps (u + v) / L``    truncnormal of sd ``sigma`` on ``[-1, 1]``; boundary: uniform
Eq. 16)           ``|u|, |v| <= 1``            on the rhombus' edges (``|u| = 1`` or ``|v| = 1``)
================  ==========================  ==========================================================

(``|L tau +- 2 sigma| <= 2 eps`` is ``|u|, |v| <= 1``: the rhombus is the
image of a square, and the map sends uniform laws to uniform laws.)

Pose errors
-----------
The first-order pose error is linear in the source values ``z`` ``(K,)``
(mm, rad): ``dX = J z`` with ``J`` ``(3, K)`` the columns of
:func:`pmaccuracy.model.sources.first_order_error` for unit values of each variable
(:func:`error_jacobian`). ``n`` samples ``Z`` ``(n, K)`` give ``dX = Z J^T``
at every pose at once (the same samples at each pose of a region);
``dp = |(dx, dy)|``.

RSS beside Monte Carlo
----------------------
The variables are uncorrelated with mean 0 (independent sources; disk
components and ``sigma, tau`` of a rhombus are uncorrelated by symmetry), so
``var(dX_q) = sum_k J_qk^2 var(z_k)`` (:func:`rss`) with, per unit ``eps``:
interval ``1/3`` (uniform), ``1`` (boundary), ``v(sigma) = sigma^2 (1 - 2 b phi(b) / (2 Phi(b) - 1))``,
``b = 1/sigma`` (truncnormal); each disk component ``E r^2 / 2``: ``1/4``, ``1/2``,
``sigma^2 - exp(-1/2sigma^2) / (2 (1 - exp(-1/2sigma^2)))``; rhombus
``var sigma = eps^2 w / 2``, ``var tau = 2 eps^2 w / L^2`` with ``w = var u``:
``1/3``, ``2/3``, ``v(sigma)``. The RSS of ``dp`` is its root mean square
``sqrt(var dx + var dy)``.

Monte Carlo error
-----------------
With ``n`` samples: the standard error of a mean ``s / sqrt(n)``; of a
standard deviation ``sqrt((m4 - s^4) / n) / (2 s)`` (``m4`` the fourth central
moment); of an exceedance probability ``sqrt(p (1 - p) / n)`` (binomial); a
percentile ``x_p`` of ``|dq|`` comes with the distribution-free 95 % interval
of order statistics ``[x_(lo), x_(hi)]``, ranks ``n p -+ 1.96 sqrt(n p (1 - p))``.

Units: mm and rad in the arrays; ``dphi`` in degrees in summaries (keys ending in ``_deg``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..model import _tomlio
from .._display import html_table, summary
from ..errors import ConfigError, PoseError
from ..model.plausibility import check_orientations
from ..model.sources import ErrorSources, JointDisplacements, refuse_first_order_only
from ..io.resolve import load_clearances
from ..io.resolve import robot_arg
from ..kinematics import as_poses, inverse_kinematics
from ..model.sources import first_order_error
from .bounds import max_pose_errors
from .maps import error_map
from .maps import save_map
from .nonlinear import joint_displaced_pose

#: Laws of a source inside its set.
LAWS = ("uniform", "truncnormal", "boundary")
#: Source keys of :mod:`pmaccuracy.model.sources` and the shape of their sets.
SHAPES = {"radial": "disk", "position": "disk", "angular": "interval", "direction": "interval",
          "actuator": "interval", "length": "interval", "lateral": "rhombus"}
#: Summarized quantities: dx, dy, dp (mm), dphi (rad in arrays, deg in summaries).
QUANTITIES = ("dx", "dy", "dp", "dphi")
#: z of the two-sided 95 % interval of a percentile (order statistics, normal approximation of the binomial).
Z95 = 1.959963984540054
#: Sample values kept in memory at once when a region is evaluated (chunks of poses).
MAX_VALUES_IN_MEMORY = 1 << 23


# ============================================================================ laws
@dataclass(frozen=True)
class SourceLaw:
    """The law of a source inside its set: ``kind`` in :data:`LAWS`; ``sigma`` (truncnormal) the standard
    deviation as a fraction of the half-width (> 0)."""

    kind: str = "uniform"
    sigma: float = 0.5

    def __post_init__(self) -> None:
        if self.kind not in LAWS:
            raise ConfigError(f"unknown law {self.kind!r} (choose from {', '.join(LAWS)})", key="kind")
        if not (math.isfinite(self.sigma) and self.sigma > 0):
            raise ConfigError(f"must be a positive fraction of the half-width, got {self.sigma}", key="sigma")

    def label(self) -> str:
        return f"truncnormal(sigma={self.sigma:g})" if self.kind == "truncnormal" else self.kind


@dataclass(frozen=True)
class Distribution:
    """Laws of the error sources: one per source key (:data:`SHAPES`), ``default`` for the others.

    File format (TOML)::

        name = "loaded revolutes"
        default = "uniform"                    # law of the keys not listed (default: uniform)
        radial = "boundary"                    # a law by name ...
        angular = { kind = "truncnormal", sigma = 0.5 }   # ... or a table

    Example
    -------
    >>> Distribution.from_dict({"radial": "boundary"}).law("radial").kind
    'boundary'
    """

    laws: tuple[tuple[str, SourceLaw], ...] = ()
    default: SourceLaw = field(default_factory=SourceLaw)
    name: str = "uniform"

    def law(self, key: str) -> SourceLaw:
        return dict(self.laws).get(key, self.default)

    def describe(self) -> dict[str, str]:
        """``{source key: law label}`` for every key."""
        return {key: self.law(key).label() for key in SHAPES}

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "Distribution":
        _tomlio.reject_unknown(data, {"name", "description", "default", *SHAPES}, source=source, where="")

        def parse(value: Any, key: str) -> SourceLaw:
            if isinstance(value, str):
                value = {"kind": value}
            if not isinstance(value, dict):
                raise ConfigError(f"must be a law name ({', '.join(LAWS)}) or a table {{kind = ..., sigma = ...}}",
                                  source=source, key=key)
            _tomlio.reject_unknown(value, {"kind", "sigma"}, source=source, where=key)
            kind = value.get("kind", "uniform")
            if kind not in LAWS:
                raise ConfigError(f"unknown law {kind!r} (choose from {', '.join(LAWS)})", source=source,
                                  key=f"{key}.kind")
            sigma = _tomlio.number(value, "sigma", source=source, where=key, default=0.5)
            if not sigma > 0:
                raise ConfigError("must be a positive fraction of the half-width", source=source, key=f"{key}.sigma")
            return SourceLaw(kind, float(sigma))

        default = parse(data.get("default", "uniform"), "default")
        laws = tuple((key, parse(data[key], key)) for key in SHAPES if key in data)
        name = data.get("name", source)
        if not isinstance(name, str):
            raise ConfigError("must be a string", source=source, key="name")
        return cls(laws=laws, default=default, name=name)

    @classmethod
    def load(cls, spec: "Distribution | str | Path | None") -> "Distribution":
        """A :class:`Distribution`, a TOML file path, a law name for every source, or None (uniform)."""
        if spec is None:
            return cls()
        if isinstance(spec, Distribution):
            return spec
        if str(spec) in LAWS:
            return cls(default=SourceLaw(str(spec)), name=str(spec))
        data, source = _tomlio.read_spec(spec, kind="distribution", folder=None)
        if isinstance(data, dict) and not ({"default", *SHAPES} & set(data)):
            # an empty file (or one with only a name) would silently mean "uniform everywhere"
            raise ConfigError(f"sets no law: give default = \"uniform\", \"truncnormal\" or \"boundary\", or a "
                              f"law per kind of source ({', '.join(SHAPES)})", source=source)
        return cls.from_dict(data, source=source)


# ============================================================================ variables
@dataclass(frozen=True)
class Term:
    """One error source: ``key`` of joint ``joint`` of leg ``leg`` (0-based), half-width ``eps`` (mm or rad),
    guide block length ``block_length`` (mm, rhombus only); its variables start at column ``start``."""

    key: str
    leg: int
    joint: int
    eps: float
    block_length: float
    start: int

    @property
    def shape(self) -> str:
        return SHAPES[self.key]

    @property
    def size(self) -> int:
        return 1 if self.shape == "interval" else 2


def as_sources(robot, clearances) -> ErrorSources:
    """Per-joint :class:`~pmaccuracy.model.sources.ErrorSources` of a clearance spec (preset, path, object), checked
    against the robot; the 3-PPR clearance format is converted."""
    sources = load_clearances(clearances, robot)
    if not isinstance(sources, ErrorSources):
        sources = ErrorSources.from_clearance_set(sources)
    return refuse_first_order_only(sources.check(robot), "the statistics")


def source_terms(sources: ErrorSources) -> tuple[Term, ...]:
    """The sources with a non-zero half-width, leg by leg and joint by joint, with their variable columns."""
    terms, start = [], 0
    for i, leg in enumerate(sources.legs):
        for k, joint in enumerate(leg):
            for key in SHAPES:
                eps = float(getattr(joint, key))
                if eps > 0:
                    t = Term(key, i, k, eps, float(joint.block_length), start)
                    terms.append(t)
                    start += t.size
    return tuple(terms)


def n_variables(terms: tuple[Term, ...]) -> int:
    return terms[-1].start + terms[-1].size if terms else 0


def to_displacements(terms: tuple[Term, ...], Z: np.ndarray) -> JointDisplacements:
    """Source values ``Z`` ``(..., K)`` (mm, rad) as :class:`~pmaccuracy.model.sources.JointDisplacements` ``(..., 3, 3)``.

    Disk variables are the (x, y) of the translation ``shift``; a rhombus' are ``(sigma, tau)``.
    """
    Z = np.asarray(Z, dtype=float)
    out = JointDisplacements.zeros(Z.shape[:-1])
    field_of = {"angular": "tilt", "direction": "turn", "actuator": "dq", "length": "dl"}
    for t in terms:
        c = t.start
        if t.shape == "disk":
            out.shift[..., t.leg, t.joint] += Z[..., c] + 1j * Z[..., c + 1]
        elif t.shape == "rhombus":
            out.sigma[..., t.leg, t.joint] += Z[..., c]
            out.tau[..., t.leg, t.joint] += Z[..., c + 1]
        else:
            getattr(out, field_of[t.key])[..., t.leg, t.joint] += Z[..., c]
    return out


def error_jacobian(robot, sources: ErrorSources, poses: np.ndarray) -> np.ndarray:
    """``J`` ``(..., 3, K)``: first-order pose error [mm, mm, rad] per unit value of each variable at poses
    ``(..., 3)``.

    Column ``k`` is :func:`pmaccuracy.model.sources.first_order_error` of the configuration with variable ``k`` at 1
    (mm or rad) and the others at 0; the error is linear, so ``dX = J z``.
    """

    poses = np.asarray(poses, dtype=float)
    terms = source_terms(sources)
    K = n_variables(terms)
    if K == 0:
        return np.zeros(poses.shape[:-1] + (3, 0))
    joints = inverse_kinematics(robot, poses).joints
    unit = to_displacements(terms, np.eye(K))  # fields (K, 3, 3)
    err = first_order_error(robot, joints[..., None, :, :], poses[..., None, :], unit)  # (..., K, 3)
    return np.swapaxes(err, -1, -2)


# ============================================================================ sampling
def _truncnormal_unit(rng: np.random.Generator, sigma: float, size) -> np.ndarray:
    """Normal of sd ``sigma`` cut to [-1, 1] by inverting its CDF."""
    from scipy.special import ndtr, ndtri

    lo = ndtr(-1.0 / sigma)
    return sigma * ndtri(lo + rng.random(size) * (1.0 - 2.0 * lo))


def _unit_interval(rng, law: SourceLaw, n: int) -> np.ndarray:
    if law.kind == "uniform":
        return rng.uniform(-1.0, 1.0, n)
    if law.kind == "boundary":
        return np.where(rng.random(n) < 0.5, -1.0, 1.0)
    return _truncnormal_unit(rng, law.sigma, n)


def _unit_disk(rng, law: SourceLaw, n: int) -> np.ndarray:
    angle = rng.uniform(0.0, 2 * np.pi, n)
    u = rng.random(n)
    if law.kind == "uniform":
        r = np.sqrt(u)
    elif law.kind == "boundary":
        r = np.ones(n)
    else:
        s2 = law.sigma ** 2
        r = np.sqrt(-2.0 * s2 * np.log1p(u * np.expm1(-0.5 / s2)))
    return np.stack([r * np.cos(angle), r * np.sin(angle)], axis=-1)


def _unit_square(rng, law: SourceLaw, n: int) -> np.ndarray:
    """``(u, v)`` ``(n, 2)`` in the square ``[-1, 1]^2``; boundary: uniform on its perimeter."""
    if law.kind != "boundary":
        return np.stack([_unit_interval(rng, law, n), _unit_interval(rng, law, n)], axis=-1)
    side = rng.integers(0, 4, n)
    t = rng.uniform(-1.0, 1.0, n)
    edge = np.where(side % 2 == 0, 1.0, -1.0)
    return np.where((side < 2)[:, None], np.stack([edge, t], -1), np.stack([t, edge], -1))


def sample_sources(sources: ErrorSources, n: int, seed: int | np.random.Generator | None = 0,
                   distribution: Distribution | str | None = None) -> np.ndarray:
    """``n`` independent draws of every source value ``Z`` ``(n, K)`` (mm, rad), columns as in :func:`source_terms`.

    Each source follows its law (module docstring) scaled to its half-width;
    ``seed``: ``numpy.random.default_rng(seed)`` (or a Generator).
    """
    if int(n) != n or n < 1:
        raise ConfigError(f"the number of samples must be a whole number >= 1, got {n}", key="samples")
    n = int(n)
    distribution = Distribution.load(distribution)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    terms = source_terms(sources)
    Z = np.zeros((n, n_variables(terms)))
    for t in terms:
        law = distribution.law(t.key)
        c = t.start
        if t.shape == "interval":
            Z[:, c] = t.eps * _unit_interval(rng, law, n)
        elif t.shape == "disk":
            Z[:, c:c + 2] = t.eps * _unit_disk(rng, law, n)
        else:
            uv = _unit_square(rng, law, n)
            Z[:, c] = t.eps * (uv[:, 0] - uv[:, 1]) / 2
            Z[:, c + 1] = t.eps * (uv[:, 0] + uv[:, 1]) / t.block_length
    return Z


def unit_variance(shape: str, law: SourceLaw) -> float:
    """Variance per ``eps^2`` of an interval value, of one disk component, or of ``u`` of a rhombus (docstring)."""
    from scipy.special import ndtr

    s = law.sigma
    if shape == "disk":
        if law.kind == "uniform":
            return 0.25
        if law.kind == "boundary":
            return 0.5
        a = 0.5 / s ** 2
        return s ** 2 - 0.5 * math.exp(-a) / -math.expm1(-a)
    if law.kind == "uniform":
        return 1.0 / 3.0
    if law.kind == "boundary":
        return 1.0 if shape == "interval" else 2.0 / 3.0
    b = 1.0 / s
    pdf = math.exp(-0.5 * b * b) / math.sqrt(2 * math.pi)
    return s ** 2 * (1.0 - 2.0 * b * pdf / (2.0 * float(ndtr(b)) - 1.0))


def variable_variances(sources: ErrorSources, distribution: Distribution | str | None = None) -> np.ndarray:
    """``var(z_k)`` ``(K,)`` (mm^2, rad^2) of every variable under the laws (module docstring)."""
    distribution = Distribution.load(distribution)
    terms = source_terms(sources)
    out = np.zeros(n_variables(terms))
    for t in terms:
        w = unit_variance(t.shape, distribution.law(t.key)) * t.eps ** 2
        c = t.start
        if t.shape == "interval":
            out[c] = w
        elif t.shape == "disk":
            out[c:c + 2] = w
        else:
            out[c] = w / 2
            out[c + 1] = 2 * w / t.block_length ** 2
    return out


def rss(J: np.ndarray, variances: np.ndarray) -> dict[str, np.ndarray]:
    """Analytic standard deviations of the linear model: ``dx, dy`` (mm), ``dphi`` (rad) = ``sqrt(sum_k J_qk^2
    var z_k)``, and ``dp`` = the root mean square ``sqrt(var dx + var dy)`` (mm); each ``(...)`` for ``J``
    ``(..., 3, K)``."""
    var = np.einsum("...qk,k->...q", np.asarray(J) ** 2, np.asarray(variances))
    return {"dx": np.sqrt(var[..., 0]), "dy": np.sqrt(var[..., 1]), "dphi": np.sqrt(var[..., 2]),
            "dp": np.sqrt(var[..., 0] + var[..., 1])}


def sample_pose_errors(robot, clearances, poses: np.ndarray, n: int, *, seed: int | np.random.Generator | None = 0,
                       distribution: Distribution | str | None = None) -> np.ndarray:
    """First-order pose errors ``(n, ..., 3)`` [mm, mm, rad] of ``n`` random source states at poses ``(..., 3)``.

    Example
    -------
    >>> e = sample_pose_errors("aalborg_3ppr", "case1", [0.0, 0.0, 0.0], 1000, seed=1)
    >>> e.shape
    (1000, 3)
    """

    robot = robot_arg(robot)
    sources = as_sources(robot, clearances)
    J = error_jacobian(robot, sources, np.asarray(poses, dtype=float))
    Z = sample_sources(sources, n, seed, distribution)
    return np.einsum("...qk,sk->s...q", J, Z)


def exact_pose_errors(robot, sources: ErrorSources, pose: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Exact pose errors ``(n, 3)`` [mm, mm, rad] of source states ``Z`` ``(n, K)`` at one pose ``(3,)``: the
    loops closed with the sources inserted (:func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`), minus the pose."""

    pose = np.asarray(pose, dtype=float)
    poses = np.broadcast_to(pose, (Z.shape[0], 3)).copy()
    d = joint_displaced_pose(robot, poses, to_displacements(source_terms(sources), Z)) - poses
    d[:, 2] = np.angle(np.exp(1j * d[:, 2]))
    return d


# ============================================================================ statistics
def _quantities(E: np.ndarray) -> dict[str, np.ndarray]:
    """``dx, dy, dp, dphi`` ``(n, ...)`` of errors ``(n, ..., 3)``."""
    return {"dx": E[..., 0], "dy": E[..., 1], "dp": np.hypot(E[..., 0], E[..., 1]), "dphi": E[..., 2]}


def order_statistic_interval(n: int, p: float, z: float = Z95) -> tuple[int, int]:
    """0-based ranks ``(lo, hi)`` of the sorted sample bracketing the ``p``-quantile with ~95 % confidence:
    ``n p -+ z sqrt(n p (1 - p))``, clipped to ``[0, n - 1]`` (distribution-free)."""
    half = z * math.sqrt(n * p * (1 - p))
    lo = int(math.floor(n * p - half)) - 1
    hi = int(math.ceil(n * p + half))
    return max(lo, 0), min(hi, n - 1)


def sample_statistics(values: np.ndarray, *, percentiles=(95.0, 99.0), thresholds: float | np.ndarray | None = None
                      ) -> dict[str, np.ndarray]:
    """Monte Carlo statistics of one quantity, samples on axis 0: ``values`` ``(n, ...)``.

    Returns arrays ``(...)``: ``mean``, ``se_mean`` (``s / sqrt(n)``), ``std`` (``ddof = 1``), ``se_std``
    (``sqrt((m4 - s^4) / n) / (2 s)``), ``max_abs``; for each percentile ``p`` of ``|values|``: ``p{p}``
    and its 95 % interval ``p{p}_lo, p{p}_hi`` (order statistics, :func:`order_statistic_interval`); with
    ``thresholds`` (broadcasting against ``(...)``): ``exceed = P(|values| > threshold)`` and
    ``se_exceed = sqrt(p (1 - p) / n)``.
    """
    v = np.asarray(values, dtype=float)
    n = v.shape[0]
    mean = v.mean(axis=0)
    dev = v - mean
    m2 = np.mean(dev ** 2, axis=0)
    m4 = np.mean(dev ** 4, axis=0)
    std = np.sqrt(m2 * n / max(n - 1, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        se_std = np.where(std > 0, np.sqrt(np.maximum(m4 - m2 ** 2, 0.0) / n) / (2 * np.where(std > 0, std, 1)), 0.0)
    a = np.sort(np.moveaxis(np.abs(v), 0, -1), axis=-1)  # samples last: a contiguous sort per pose
    out = {"mean": mean, "se_mean": std / math.sqrt(n), "std": std, "se_std": se_std, "max_abs": a[..., -1]}
    for p in percentiles:
        key = f"p{p:g}"
        out[key] = np.quantile(a, p / 100.0, axis=-1)
        lo, hi = order_statistic_interval(n, p / 100.0)
        out[f"{key}_lo"], out[f"{key}_hi"] = a[..., lo], a[..., hi]
    if thresholds is not None:
        p_ex = np.mean(np.abs(v) > np.asarray(thresholds), axis=0)
        out["exceed"] = p_ex
        out["se_exceed"] = np.sqrt(p_ex * (1 - p_ex) / n)
    return out


def _check_common(percentiles, thresholds: dict[str, float]) -> tuple[tuple[float, ...], dict[str, float]]:
    pct = tuple(float(p) for p in percentiles)
    for p in pct:
        if not (0 < p < 100):
            raise ConfigError(f"percentiles must lie strictly between 0 and 100, got {p:g}", key="percentile")
    thr = {}
    for key, value in (thresholds or {}).items():
        q = key[:-4] if key.endswith("_deg") else key
        if q not in QUANTITIES or (q == "dphi") != key.endswith("_deg"):
            raise ConfigError(f"unknown quantity {key!r} (choose from dx, dy, dp in mm and dphi_deg in deg)",
                              key="threshold")
        if not (math.isfinite(value) and value >= 0):
            raise ConfigError(f"{key}: must be a finite value >= 0, got {value}", key="threshold")
        thr[q] = math.radians(value) if q == "dphi" else float(value)
    return pct, thr


@dataclass(frozen=True)
class PoseStatistics:
    """The distribution of the pose error at one pose (:func:`pose_statistics`).

    Attributes
    ----------
    robot, clearances : names;  distribution : its description (:meth:`Distribution.describe`)
    pose : ``(3,)`` [x mm, y mm, phi rad];  samples, seed : the Monte Carlo settings
    quantities : per ``dx, dy, dp`` (mm) and ``dphi_deg`` (deg) a dict of floats: the
        :func:`sample_statistics` (mean, std, percentiles with their confidence bounds, exceedance with its
        standard error), ``rss`` (analytic std; root mean square for dp), ``worst`` (the exact worst case of
        :func:`~pmaccuracy.accuracy.bounds.max_pose_errors`) and, with a threshold, ``threshold``
    exact_check : with ``exact_samples``: ``samples`` and the largest difference between the exact and the
        first-order errors (``max_diff_dx``, ``max_diff_dy`` mm, ``max_diff_dphi_deg``); else ``None``
    """

    robot: str
    clearances: str
    distribution: str
    pose: np.ndarray
    samples: int
    seed: int | None
    quantities: dict[str, dict[str, float]]
    exact_check: dict[str, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``robot, clearances, distribution, pose`` (x, y mm, phi_deg), ``samples, seed,
        quantities`` and, when computed, ``exact_check`` (the command line's ``--format json``)."""
        out = {"robot": self.robot, "clearances": self.clearances, "distribution": self.distribution,
               "pose": {"x": float(self.pose[0]), "y": float(self.pose[1]),
                        "phi_deg": float(np.degrees(self.pose[2]))},
               "samples": self.samples, "seed": self.seed,
               "quantities": {q: dict(rec) for q, rec in self.quantities.items()}}
        if self.exact_check is not None:
            out["exact_check"] = dict(self.exact_check)
        return out

    def records(self) -> list[dict]:
        """One row per quantity: its statistics (mm or deg)."""
        return [{"quantity": q, **rec} for q, rec in self.quantities.items()]

    def __repr__(self) -> str:
        parts = [f"{q} std {rec['std']:.4g}, worst {rec['worst']:.4g} {'deg' if q == 'dphi_deg' else 'mm'}"
                 for q, rec in self.quantities.items()]
        return summary("PoseStatistics", 1, [f"{self.samples} samples"] + parts)

    def _repr_html_(self) -> str:
        keep = ("quantity", "mean", "std", "rss", "p95", "p99", "exceed", "worst")
        return html_table(f"Pose error statistics ({self.samples} samples; mm, deg)",
                          [{k: r[k] for k in keep if k in r} for r in self.records()])


def pose_statistics(robot, clearances, pose, *, samples: int = 100_000, seed: int | None = 0,
                    distribution: Distribution | str | None = None, percentiles=(95.0, 99.0),
                    thresholds: dict[str, float] | None = None, exact_samples: int = 0) -> PoseStatistics:
    """Distribution of the pose error at one pose ``(3,)`` [mm, mm, rad]: Monte Carlo, RSS and the worst case.

    ``thresholds``: ``{"dx" | "dy" | "dp": mm, "dphi_deg": deg}`` for ``P(|dq| > threshold)``.
    ``exact_samples``: also close the loops exactly for that many of the samples and report the largest
    difference from the first-order errors.

    Returns a :class:`PoseStatistics` (``.to_dict()`` for JSON).

    Example
    -------
    >>> st = pose_statistics("aalborg_3ppr", "case1", [0.0, 0.0, 0.0], samples=2000)
    >>> st.quantities["dp"]["p95"] <= st.quantities["dp"]["worst"]
    True
    """
    check_orientations(pose, "pose", poses=True)
    robot = robot_arg(robot)
    sources = as_sources(robot, clearances)
    distribution = Distribution.load(distribution)
    pct, thr = _check_common(percentiles, thresholds or {})
    pose = as_poses(pose)
    if pose.shape != (3,):
        raise PoseError(f"pose must be one pose (3,) = [x mm, y mm, phi rad], got shape {pose.shape} (several "
                        f"poses: call it once per pose, or region_statistics for maps)")
    worst = max_pose_errors(robot, sources, pose)
    Z = sample_sources(sources, samples, seed, distribution)
    J = error_jacobian(robot, sources, pose)
    E = Z @ J.T
    sd = rss(J, variable_variances(sources, distribution))
    worst_q = {"dx": worst.dx_max, "dy": worst.dy_max, "dp": worst.dp_max, "dphi": worst.dphi_max}
    quantities = {}
    for q, values in _quantities(E).items():
        stats = sample_statistics(values, percentiles=pct, thresholds=thr.get(q))
        scale = math.degrees(1) if q == "dphi" else 1.0
        rec = {k: float(v) * (1.0 if k.endswith("exceed") else scale) for k, v in stats.items()}
        if q in thr:
            rec["threshold"] = thr[q] * scale
        rec["rss"] = float(sd[q]) * scale
        rec["worst"] = float(worst_q[q]) * scale
        quantities["dphi_deg" if q == "dphi" else q] = rec
    check = None
    if exact_samples:
        m = min(int(exact_samples), Z.shape[0])
        exact = exact_pose_errors(robot, sources, pose, Z[:m])
        diff = np.abs(exact - E[:m]).max(axis=0)
        check = {"samples": m, "max_diff_dx": float(diff[0]), "max_diff_dy": float(diff[1]),
                 "max_diff_dphi_deg": float(np.degrees(diff[2]))}
    return PoseStatistics(robot=robot.name, clearances=sources.name, distribution=distribution.describe(),
                          pose=pose.copy(), samples=int(samples), seed=seed, quantities=quantities,
                          exact_check=check)


#: Variables of a percentile map (besides the worst case): name -> (units of dp/dx/dy, long name).
def _map_variables(pct: tuple[float, ...], thr: dict[str, float]) -> dict[str, tuple[str, str]]:
    out = {}
    for q in QUANTITIES:
        unit = "deg" if q == "dphi" else "mm"
        out[f"{q}_std"] = (unit, f"Monte Carlo standard deviation of {q}" if q != "dp" else
                           "Monte Carlo standard deviation of dp")
        out[f"{q}_rss"] = (unit, f"analytic RSS standard deviation of {q}" if q != "dp" else
                           "analytic root mean square of dp")
        for p in pct:
            out[f"{q}_p{p:g}"] = (unit, f"{p:g}th percentile of |{q}| (Monte Carlo)")
        if q in thr:
            out[f"{q}_exceed"] = ("1", f"P(|{q}| > {thr[q] * (math.degrees(1) if q == 'dphi' else 1):g} {unit})")
        out[f"{q}_max"] = (unit, f"worst case of |{q}| (Eq. 21-22)")
    return out


def region_statistics(robot, clearances, phis, grid: int = 21, *, samples: int = 10_000, seed: int | None = 0,
                      distribution: Distribution | str | None = None, percentiles=(95.0,),
                      thresholds: dict[str, float] | None = None, region=None):
    """Percentile maps over constant-orientation workspaces: an ``xarray.Dataset`` with dims ``(phi, y, x)``.

    The grid and the worst case are those of :func:`pmaccuracy.accuracy.maps.error_map` (``phis`` in rad; ``phi``
    coordinate in degrees; NaN outside the workspace). Variables per quantity ``q`` in dx, dy, dp (mm) and
    dphi (deg): ``q_std`` (Monte Carlo), ``q_rss`` (analytic), ``q_p{p}`` (percentiles of ``|q|``),
    ``q_exceed`` (``P(|q| > threshold)``, with a threshold) and ``q_max`` (worst case). The same ``samples``
    source states are used at every pose; the Monte Carlo error is in the attributes
    (``exceed_se_max = 0.5 / sqrt(n)``, the binomial bound; for each percentile map ``q_p{p}_error``: the
    largest half-width over the map of the percentile's 95 % order-statistic interval, units of ``q``, and
    ``q_p{p}_ratio_error``: the largest half-width divided by the worst case ``q_max`` at its pose).
    ``region``: a shape of :mod:`pmaccuracy.accuracy.regions` (mm) or None: as in
    :func:`~pmaccuracy.accuracy.maps.error_map`, the grid is cut to its bounding box and the points outside it
    are NaN (attribute ``region``).
    """
    import xarray as xr

    check_orientations(phis, "phis")
    robot = robot_arg(robot)
    sources = as_sources(robot, clearances)
    distribution = Distribution.load(distribution)
    pct, thr = _check_common(percentiles, thresholds or {})
    Z = sample_sources(sources, samples, seed, distribution)  # checks samples first
    ds = error_map(robot, sources, phis, grid, progress=False, region=region)
    variances = variable_variances(sources, distribution)
    phi_rad = np.radians(ds.phi.values)
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    shape = (len(phi_rad),) + X.shape
    inside = np.isfinite(ds["dx_max"].values)
    names = _map_variables(pct, thr)
    values = {name: np.full(shape, np.nan) for name in names}
    idx = np.argwhere(inside)
    poses = np.column_stack([X[idx[:, 1], idx[:, 2]], Y[idx[:, 1], idx[:, 2]], phi_rad[idx[:, 0]]])
    block = max(1, MAX_VALUES_IN_MEMORY // (3 * Z.shape[0]))
    to_deg = math.degrees(1)
    half = {f"{q}_p{p:g}": np.full(shape, np.nan) for q in QUANTITIES for p in pct}
    for start in range(0, poses.shape[0], block):
        sel = idx[start:start + block]
        where = (sel[:, 0], sel[:, 1], sel[:, 2])
        J = error_jacobian(robot, sources, poses[start:start + block])
        E = np.einsum("pqk,sk->spq", J, Z)
        sd = rss(J, variances)
        for q, v in _quantities(E).items():
            scale = to_deg if q == "dphi" else 1.0
            st = sample_statistics(v, percentiles=pct, thresholds=thr.get(q))
            values[f"{q}_std"][where] = st["std"] * scale
            values[f"{q}_rss"][where] = sd[q] * scale
            for p in pct:
                values[f"{q}_p{p:g}"][where] = st[f"p{p:g}"] * scale
                half[f"{q}_p{p:g}"][where] = 0.5 * (st[f"p{p:g}_hi"] - st[f"p{p:g}_lo"]) * scale
            if q in thr:
                values[f"{q}_exceed"][where] = st["exceed"]
    for q in QUANTITIES:
        values[f"{q}_max"] = ds[f"{q}_max"].values.copy()
    data_vars = {name: (("phi", "y", "x"), values[name], {"units": u, "long_name": ln})
                 for name, (u, ln) in names.items()}
    attrs = dict(ds.attrs)
    attrs.update({"title": f"Pose error statistics of {robot.name} with clearances {sources.name}",
                  "method": "Monte Carlo of the first-order error (independent sources inside their sets) and "
                            "analytic RSS; worst case: exact first-order maxima (Eq. 21-22)",
                  "distribution": "; ".join(f"{k}: {v}" for k, v in distribution.describe().items()),
                  "samples": str(int(samples)), "seed": str(seed),
                  "percentile_interval": "95 % order-statistic interval, ranks n p -+ 1.96 sqrt(n p (1 - p))",
                  "exceed_se_max": repr(0.5 / math.sqrt(samples))})
    for q, t in thr.items():
        attrs[f"{q}_threshold"] = repr(t * (to_deg if q == "dphi" else 1.0))
    for key, h in half.items():     # the Monte Carlo error of each percentile map (figures draw no finer)
        q = key.split("_")[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(values[f"{q}_max"] > 0, h / values[f"{q}_max"], np.nan)
        attrs[f"{key}_error"] = repr(float(np.nanmax(h)) if np.isfinite(h).any() else float("nan"))
        attrs[f"{key}_ratio_error"] = repr(float(np.nanmax(ratio)) if np.isfinite(ratio).any() else float("nan"))
    return xr.Dataset(data_vars, coords=ds.coords, attrs=attrs)


def save_region_statistics(ds, path: str | Path) -> Path:
    """Write :func:`region_statistics` as NetCDF (``.nc``) or CSV (``.csv``: the inside points, columns ``x, y,
    phi_deg`` and every variable; the ``dphi`` columns, in degrees, get a ``_deg`` suffix). Returns the path."""

    path = Path(path)
    if path.suffix.lower() != ".csv":
        return save_map(ds, path)
    frame = ds.to_dataframe().reset_index()
    frame = frame[np.isfinite(frame["dx_max"])]
    names = {"phi": "phi_deg", **{n: f"{n}_deg" for n in ds.data_vars if n.startswith("dphi_")}}
    frame = frame.rename(columns=names)[["x", "y", "phi_deg", *(names.get(n, n) for n in ds.data_vars)]]
    frame.to_csv(path, index=False, float_format="%.9g")
    return path


def summarize_region(ds) -> dict[str, Any]:
    """What a report section needs from :func:`region_statistics`, JSON-ready.

    ``samples, seed, distribution`` and ``orientations``: per orientation (deg, as text) and quantity
    (``dx, dy, dp`` in mm, ``dphi_deg`` in deg) the ``[min, max]`` over the workspace of ``std, rss``, each
    percentile ``p{p}``, ``exceed`` (with a threshold) and ``max`` (the worst case), and
    ``p{p}_over_max``: the mean over the workspace of percentile / worst case.
    """
    pct = sorted({name.split("_p", 1)[1] for name in ds.data_vars if name.startswith("dp_p")}, key=float)
    layers = {}
    for phi in ds.phi.values:
        layer = ds.sel(phi=phi)
        entry = {}
        for q in QUANTITIES:
            rec = {}
            for stat in ("std", "rss", *(f"p{p}" for p in pct), "exceed", "max"):
                name = f"{q}_{stat}"
                if name in ds.data_vars:
                    rec[stat] = [float(layer[name].min()), float(layer[name].max())]
            for p in pct:
                rec[f"p{p}_over_max"] = float((layer[f"{q}_p{p}"] / layer[f"{q}_max"]).mean())
            entry["dphi_deg" if q == "dphi" else q] = rec
        layers[f"{phi:g}"] = entry
    seed = ds.attrs.get("seed")
    return {"samples": int(ds.attrs.get("samples", 0)),
            "seed": int(seed) if str(seed).lstrip("-").isdigit() else seed,
            "distribution": ds.attrs.get("distribution"), "orientations": layers}
