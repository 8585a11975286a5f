"""Statistics of the pose error of spatial robots at a pose: Monte Carlo, exact covariance (RSS), worst case.

The spatial counterpart of :mod:`pmaccuracy.accuracy.distributions`: the worst case
(:func:`~pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`) answers "how far can the platform be off",
this module "how far is it off, typically", when every error source takes a random value inside its set,
independently of the others.

Model
-----
At a pose, Eq. 1 of :mod:`~pmaccuracy.accuracy.spatial_bounds` gives the platform's first-order error twist
``t = [dx, dy, dz mm, drx, dry, drz rad]`` ``(6,)`` as

    t = sum_s M_s x_s,   M_s (6, d_s) (half-width included),   x_s in the unit set of source s,

the unit set being the segment ``[-1, 1]`` (``d = 1``), the disc (``d = 2``) or the ball (``d = 3``) of radius 1.

Laws (:data:`LAWS`), the same for every source, ``x_s`` independent across sources:

* ``uniform``: uniform over the segment, the disc's area, the ball's volume; drawn exactly as
  ``x = U^(1/d) u`` with ``U`` uniform on ``[0, 1]`` and ``u`` a uniform direction (a normalized standard
  Gaussian ``d``-vector; ``d = 1``: a random sign). ``Cov(x) = I / (d + 2)`` (a segment ``1/3``, a disc
  ``1/4``, a ball ``1/5``).
* ``normal``: an isotropic Gaussian ``N(0, sigma^2 I)`` (``sigma`` a fraction of the half-width, default
  ``1/3``) **truncated** (conditioned, not clipped) to the unit set: its direction is uniform and
  ``|x|^2 / sigma^2`` a chi-square of ``d`` degrees of freedom conditioned on ``<= c = 1 / sigma^2``, drawn
  exactly by inverting its CDF, ``|x| = sigma sqrt(2 P^-1(d/2, U P(d/2, c/2)))`` (``P`` the regularized
  lower incomplete gamma function). ``Cov(x) = sigma^2 P(d/2 + 1, c/2) / P(d/2, c/2) I``.

Analytic covariance (exact for the linear model):

    Cov(t) = sum_s v_s M_s M_s^T  (6, 6; mm^2, mm rad, rad^2),   v_s = the per-coordinate variance above,

so the RSS (standard deviation, equal to the root mean square since every mean is 0) of a component is
``sqrt(Cov_qq)``, and the root mean square of ``|dp| = |t[:3]|`` is ``sqrt(tr Cov[:3, :3])`` (``|dtheta|``
likewise with ``Cov[3:, 3:]``).

Monte Carlo error: as in :func:`pmaccuracy.accuracy.distributions.sample_statistics` (standard errors of the
mean and standard deviation, 95 % order-statistic intervals of the percentiles, binomial standard error of an
exceedance); the root mean square's ``se_rms = sd(v^2) / (2 rms sqrt(n))``.

Units: mm and rad in arrays; the summaries (:attr:`SpatialPoseStatistics.quantities`) give angles in degrees
(keys ending in ``_deg``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._display import html_table, summary
from ..errors import ConfigError, PoseError
from ..io.resolve import robot_arg
from ..kinematics.spatial import as_spatial_poses
from ..model.plausibility import check_angle_values, rotation_angles
from ..model.spatial import is_spatial
from ..model.spatial_sources import SpatialErrorSources, default_preset
from .distributions import sample_statistics
from .spatial_bounds import error_sources_at, spatial_pose_errors

#: Laws of every source inside its set (module docstring).
LAWS = ("uniform", "normal")
#: Summarized quantities: the six components (mm; rotations in deg), |dp| (mm) and |dtheta| (deg).
QUANTITIES = ("dx", "dy", "dz", "drx_deg", "dry_deg", "drz_deg", "dp", "dtheta_deg")
#: Fewest Monte Carlo samples accepted (percentiles of fewer say little).
MIN_SAMPLES = 1000
#: Default standard deviation of the ``normal`` law, as a fraction of the half-width.
DEFAULT_SIGMA = 1.0 / 3.0
_DIMS = {"segment": 1, "disc": 2, "ball": 3}
#: Samples drawn at once (cache-sized arrays).
CHUNK = 1 << 14


# ============================================================================ laws
def unit_variance(d: int, distribution: str = "uniform", sigma: float = DEFAULT_SIGMA) -> float:
    """Variance of each coordinate of ``x`` drawn in the unit ``d``-ball (``d = 1``: the segment ``[-1, 1]``)
    under ``distribution`` (module docstring): ``1 / (d + 2)`` (uniform) or
    ``sigma^2 P(d/2 + 1, c/2) / P(d/2, c/2)``, ``c = 1 / sigma^2`` (truncated normal). Dimensionless (per
    half-width squared).

    >>> unit_variance(1), unit_variance(3)
    (0.3333333333333333, 0.2)
    >>> round(unit_variance(1, "normal", 1e-3), 12)    # a narrow Gaussian: sigma^2
    1e-06
    """
    _check_law(distribution, sigma)
    if distribution == "uniform":
        return 1.0 / (d + 2)
    from scipy.special import gammainc

    c = 0.5 / sigma ** 2
    return sigma ** 2 * float(gammainc(d / 2 + 1, c) / gammainc(d / 2, c))


def sample_unit_set(rng: np.random.Generator, d: int, n: int, distribution: str = "uniform",
                    sigma: float = DEFAULT_SIGMA) -> np.ndarray:
    """``n`` independent points ``(n, d)`` of the unit ``d``-ball (``d = 1``: the segment ``[-1, 1]``) under
    ``distribution``: ``r u`` with ``u`` a uniform direction (normalized standard Gaussian) and ``r = U^(1/d)``
    (uniform) or ``r = sigma sqrt(2 P^-1(d/2, U P(d/2, c/2)))``, ``c = 1 / sigma^2`` (truncated normal);
    vectorized (module docstring).

    >>> x = sample_unit_set(np.random.default_rng(0), 3, 20000)
    >>> x.shape, bool(np.all(np.linalg.norm(x, axis=1) <= 1)), round(float(x[:, 0].var()), 2)
    ((20000, 3), True, 0.2)
    """
    _check_law(distribution, sigma)
    if d == 1:          # the segment: the direction is a sign
        if distribution == "uniform":
            return rng.uniform(-1.0, 1.0, (n, 1))
        u = np.where(rng.random((n, 1)) < 0.5, -1.0, 1.0)
    else:
        g = rng.standard_normal((n, d))
        u = g / np.sqrt(np.einsum("ij,ij->i", g, g))[:, None]
    U = rng.random(n)
    if distribution == "uniform":
        r = np.sqrt(U) if d == 2 else np.cbrt(U) if d == 3 else U ** (1.0 / d)
    else:
        from scipy.special import gammainc, gammaincinv

        c = 0.5 / sigma ** 2
        r = sigma * np.sqrt(2.0 * gammaincinv(d / 2, U * gammainc(d / 2, c)))
        r = np.minimum(r, 1.0)      # rounding of the inverse at U ~ 1
    return r[:, None] * u


def _check_law(distribution, sigma) -> None:
    if distribution not in LAWS:
        raise ConfigError(f"unknown law {distribution!r} (choose from {', '.join(LAWS)})", key="distribution")
    if not (isinstance(sigma, (int, float)) and math.isfinite(sigma) and sigma > 0):
        raise ConfigError(f"must be a positive fraction of the half-width, got {sigma!r}", key="sigma")


# ============================================================================ the model at a pose
def source_matrices(robot, sources: SpatialErrorSources, pose) -> tuple[list[np.ndarray], list]:
    """The blocks ``M_s`` ``(6, d_s)`` of Eq. 1 at one pose ``(6,)`` [x, y, z mm, rotation vector rad], one per
    source (half-width included: ``x_s`` in the unit set), and the
    :class:`~pmaccuracy.accuracy.spatial_bounds.Source` list (shape, label, half-width)."""
    _, info = error_sources_at(robot, sources, pose, keep=True)
    kept = info["sources"]
    return [np.asarray(s.matrix, dtype=float) for s in kept], kept


def twist_covariance(matrices, dims, distribution: str = "uniform", sigma: float = DEFAULT_SIGMA) -> np.ndarray:
    """Exact covariance ``(6, 6)`` (mm^2, mm rad, rad^2) of ``t = sum_s M_s x_s``:
    ``sum_s v(d_s) M_s M_s^T`` with ``v`` the per-coordinate variance of :func:`unit_variance`.

    >>> float(twist_covariance([np.eye(6)[:, :1] * 3.0], [1])[0, 0])      # a segment of half-width 3 along dx
    3.0
    """
    cov = np.zeros((6, 6))
    for M, d in zip(matrices, dims):
        cov += unit_variance(d, distribution, sigma) * (M @ M.T)
    return cov


def sample_twists(matrices, dims, n: int, seed: int | np.random.Generator | None = 0,
                  distribution: str = "uniform", sigma: float = DEFAULT_SIGMA) -> np.ndarray:
    """``n`` first-order error twists ``(n, 6)`` [mm, rad]: ``t = sum_s M_s x_s`` with each ``x_s`` drawn
    independently in its unit set (:func:`sample_unit_set`, every source of one dimension ``d`` at once), i.e.
    ``t = X M^T`` with ``X`` ``(n, sum d_s)`` the variables and ``M`` ``(6, sum d_s)`` the blocks side by side;
    in chunks of :data:`CHUNK` samples (reproducible for a given ``seed``).

    >>> t = sample_twists([np.eye(6)[:, :1]], [1], 1000, seed=1)
    >>> t.shape, float(np.abs(t[:, 1:]).max()), bool(np.abs(t[:, 0]).max() <= 1)
    ((1000, 6), 0.0, True)
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    groups = {d: [M for M, dd in zip(matrices, dims) if dd == d] for d in sorted(set(dims))}
    # the blocks of dimension d side by side, in the order of the variables drawn below: (6, k d)
    Ms = {d: np.concatenate(ms, axis=1) for d, ms in groups.items()}
    t = np.zeros((n, 6))
    for start in range(0, n, CHUNK):
        m = min(CHUNK, n - start)
        for d, M in Ms.items():
            k = len(groups[d])
            x = sample_unit_set(rng, d, m * k, distribution, sigma).reshape(m, k * d)
            t[start:start + m] += x @ M.T
    return t


# ============================================================================ statistics
def _check_inputs(samples, distribution, sigma, percentiles, thresholds):
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < MIN_SAMPLES:
        raise ConfigError(f"the number of samples must be a whole number >= {MIN_SAMPLES}, got {samples!r}",
                          key="samples")
    _check_law(distribution, sigma)
    try:
        pct = tuple(float(p) for p in percentiles)
    except (TypeError, ValueError):
        raise ConfigError(f"must be numbers strictly between 0 and 100, got {percentiles!r}",
                          key="percentiles") from None
    if not pct:
        raise ConfigError("give at least one percentile", key="percentiles")
    for p in pct:
        if not (0 < p < 100):
            raise ConfigError(f"must lie strictly between 0 and 100, got {p:g}", key="percentiles")
    thr = {}
    if thresholds is not None and not isinstance(thresholds, dict):
        raise ConfigError(f"must be a dict {{quantity: value}}, got {type(thresholds).__name__}", key="thresholds")
    for key, value in (thresholds or {}).items():
        if key not in QUANTITIES:
            raise ConfigError(f"unknown quantity {key!r} (choose from dx, dy, dz, dp in mm and drx_deg, dry_deg, "
                              f"drz_deg, dtheta_deg in deg)", key="thresholds")
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{key}: must be a number, got {value!r}", key="thresholds") from None
        if not (math.isfinite(value) and value >= 0):
            raise ConfigError(f"{key}: must be a finite value >= 0, got {value}", key="thresholds")
        thr[key] = value
    return int(samples), pct, thr


@dataclass(frozen=True)
class SpatialPoseStatistics:
    """The distribution of a spatial robot's pose error at one pose (:func:`spatial_pose_statistics`).

    Attributes
    ----------
    robot, clearances, distribution : names (``distribution``: ``"uniform"`` or ``"normal(sigma=...)"``)
    pose : ``(6,)`` [x, y, z mm, rotation vector rad];  samples, seed : the Monte Carlo settings
    quantities : per :data:`QUANTITIES` (``dx, dy, dz, dp`` mm; ``drx_deg, dry_deg, drz_deg, dtheta_deg`` deg)
        a dict of floats: ``mean, se_mean, std, se_std, max_abs``, ``mean_abs``, ``rms, se_rms`` (Monte Carlo),
        ``rss`` (analytic: the standard deviation of a component, the root mean square of dp and dtheta),
        each percentile ``p{p}`` of ``|q|`` with its 95 % interval ``p{p}_lo, p{p}_hi``, ``worst`` (exact
        worst case; dp and dtheta: certified upper bound) and ``max_over_worst``; with a threshold
        ``threshold``, ``exceed = P(|q| > threshold)`` and ``se_exceed``
    covariance : ``(6, 6)`` the exact covariance of the twist [mm, rad] (module docstring)
    within_worst : True when no sample exceeds the worst case (it must: a check of both computations)
    twists : ``(samples, 6)`` or None
        The Monte Carlo twists [mm, rad] when asked for (``keep_samples=True``), else None
    """

    robot: str
    clearances: str
    distribution: str
    pose: np.ndarray
    samples: int
    seed: int | None
    quantities: dict[str, dict[str, float]]
    covariance: np.ndarray = field(repr=False)
    within_worst: bool = True
    twists: np.ndarray | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``robot, clearances, distribution, pose`` (x, y, z mm, rotvec rad), ``samples, seed,
        within_worst, quantities`` and ``covariance`` (6 x 6 nested lists, mm and rad)."""
        return {"robot": self.robot, "clearances": self.clearances, "distribution": self.distribution,
                "pose": {k: float(v) for k, v in zip(("x", "y", "z", "rx", "ry", "rz"), self.pose)},
                "samples": self.samples, "seed": self.seed, "within_worst": bool(self.within_worst),
                "quantities": {q: dict(rec) for q, rec in self.quantities.items()},
                "covariance": self.covariance.tolist()}

    def records(self) -> list[dict]:
        """One row per quantity: its statistics (mm or deg)."""
        return [{"quantity": q, **rec} for q, rec in self.quantities.items()]

    def __repr__(self) -> str:
        parts = [f"{q} rms {rec['rms']:.4g}, worst {rec['worst']:.4g} {'deg' if q.endswith('_deg') else 'mm'}"
                 for q, rec in self.quantities.items() if q in ("dp", "dtheta_deg")]
        return summary("SpatialPoseStatistics", 1, [f"{self.samples} samples"] + parts)

    def _repr_html_(self) -> str:
        keep = ("quantity", "mean_abs", "rms", "rss", "p95", "p99", "exceed", "worst")
        return html_table(f"Spatial pose error statistics ({self.samples} samples; mm, deg)",
                          [{k: r[k] for k in keep if k in r} for r in self.records()])


def spatial_pose_statistics(robot, sources, pose, *, samples: int = 100_000, seed: int | None = 0,
                            distribution: str = "uniform", percentiles=(95.0, 99.0),
                            thresholds: dict[str, float] | None = None, sigma: float = DEFAULT_SIGMA,
                            keep_samples: bool = False) -> SpatialPoseStatistics:
    """Distribution of a spatial robot's first-order pose error at one pose ``(6,)`` [x, y, z mm, rotation
    vector rad]: Monte Carlo of ``t = sum_s M_s x_s`` ``(samples, 6)``, the exact covariance and RSS, and the
    worst case of :func:`~pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors` (module docstring).

    ``robot``: a :class:`~pmaccuracy.model.spatial.SpatialManipulator` or a preset name / TOML path;
    ``sources``: a :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset name / TOML path,
    ``"none"`` or None (the architecture's typical preset). ``distribution``: ``"uniform"`` or ``"normal"``
    (truncated isotropic Gaussian of standard deviation ``sigma`` times the half-width per coordinate).
    ``thresholds``: ``{"dx" | "dy" | "dz" | "dp": mm, "drx_deg" | "dry_deg" | "drz_deg" | "dtheta_deg": deg}``
    for ``P(|q| > threshold)``. ``keep_samples``: keep the drawn twists ``(samples, 6)`` [mm, rad] in the
    result's ``twists`` (e.g. for a histogram).

    Raises :class:`~pmaccuracy.errors.PoseError` for a pose that is not one ``(6,)`` pose (or is unreachable,
    near-singular) and :class:`~pmaccuracy.errors.ConfigError` naming ``samples`` (< 1000), ``distribution``,
    ``percentiles``, ``thresholds`` or ``sigma``.

    Example
    -------
    >>> st = spatial_pose_statistics("stewart_6ups", "ups_typical", [0, 0, 400, 0, 0, 0], samples=2000)
    >>> q = st.quantities["dp"]
    >>> q["p95"] <= q["p99"] <= q["worst"], st.within_worst
    (True, True)
    """
    n, pct, thr = _check_inputs(samples, distribution, sigma, percentiles, thresholds)
    robot = robot_arg(robot)
    if not is_spatial(robot):
        raise ConfigError(f"{robot.name} is a planar robot: use pose_statistics", key="robot")
    sources = SpatialErrorSources.load(default_preset(robot) if sources is None else sources, robot)
    if sources.architecture != robot.architecture:
        raise ConfigError(f"the error sources are of a {sources.architecture}, the robot a {robot.architecture}",
                          key="sources")
    pose = as_spatial_poses(pose)
    if pose.shape != (6,):
        raise PoseError(f"pose must be one pose (6,) = [x, y, z mm, rotation vector rad], got shape {pose.shape} "
                        f"(several poses: call it once per pose)")
    check_angle_values(rotation_angles(pose), "pose[3:] (rotation vector)")
    worst = spatial_pose_errors(robot, sources, pose)
    matrices, kept = source_matrices(robot, sources, pose)
    dims = [_DIMS[s.shape] for s in kept]
    cov = twist_covariance(matrices, dims, distribution, sigma)
    t = sample_twists(matrices, dims, n, seed, distribution, sigma)
    deg = math.degrees(1.0)
    values = {"dx": t[:, 0], "dy": t[:, 1], "dz": t[:, 2], "drx_deg": t[:, 3] * deg, "dry_deg": t[:, 4] * deg,
              "drz_deg": t[:, 5] * deg, "dp": np.linalg.norm(t[:, :3], axis=1),
              "dtheta_deg": np.linalg.norm(t[:, 3:], axis=1) * deg}
    var = np.diag(cov)
    rss = {**{q: math.sqrt(max(var[k], 0.0)) * (deg if k >= 3 else 1.0) for k, q in enumerate(QUANTITIES[:6])},
           "dp": math.sqrt(max(var[:3].sum(), 0.0)), "dtheta_deg": math.sqrt(max(var[3:].sum(), 0.0)) * deg}
    comp = worst.components
    worst_q = {"dx": comp[0], "dy": comp[1], "dz": comp[2], "drx_deg": comp[3] * deg, "dry_deg": comp[4] * deg,
               "drz_deg": comp[5] * deg, "dp": worst.dp_upper, "dtheta_deg": worst.dtheta_upper * deg}
    quantities, within = {}, True
    for q in QUANTITIES:
        v = values[q]
        stats = sample_statistics(v, percentiles=pct, thresholds=thr.get(q))
        rec = {k: float(x) for k, x in stats.items()}
        sq = v * v
        rms = math.sqrt(float(sq.mean()))
        rec["mean_abs"] = float(np.abs(v).mean())
        rec["rms"] = rms
        rec["se_rms"] = float(sq.std(ddof=1)) / (2 * rms * math.sqrt(n)) if rms > 0 else 0.0
        rec["rss"] = rss[q]
        rec["worst"] = float(worst_q[q])
        rec["max_over_worst"] = rec["max_abs"] / rec["worst"] if rec["worst"] > 0 else 0.0
        if q in thr:
            rec["threshold"] = thr[q]
        within &= rec["max_abs"] <= rec["worst"] * (1 + 1e-9) + 1e-15
        quantities[q] = rec
    label = distribution if distribution == "uniform" else f"normal(sigma={sigma:g})"
    return SpatialPoseStatistics(robot=robot.name, clearances=sources.name, distribution=label, pose=pose.copy(),
                                 samples=n, seed=seed if not isinstance(seed, np.random.Generator) else None,
                                 quantities=quantities, covariance=cov, within_worst=bool(within),
                                 twists=t if keep_samples else None)
