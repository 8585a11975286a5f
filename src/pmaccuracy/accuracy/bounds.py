r"""Exact maximum pose errors under joint clearances and tolerances (paper Sec. 4.3, Eq. 19-22), any architecture.

The paper maximizes ``(J^c_err,zeta delta^c)^2`` (Eq. 21) and
``|J^c_err,p delta^c|^2`` (Eq. 22) over the clearance constraints (Eq. 16-18)
with a local optimizer (fmincon), pose by pose. Here the problems are solved
exactly and in closed form, by one engine for every robot.

Why it is exact. By Eq. 8 (in general form: each error source's twist paired
with leg ``i``'s constraint wrench, :mod:`pmaccuracy.model.sources`) the sources
of leg ``i`` add one scalar ``e_i`` to the right-hand side of
``A [dp; dphi] = e``. For the paper's 3-PPR::

    e_i = H_theta,i dtau_b,i + H_sigma,i dsigma_g,i + H_gamma,i dtau_g,i + H_rho,i drho_i

(``H_sigma = w_i . u_i``: the guide's lateral shift acts normal to the rail; the
paper's ``H_d`` along ``v_i`` is the same when ``gamma_i = +-90 deg``). The
sources of a leg are independent of the other legs' and each set is
symmetric, so ``e_i`` ranges over ``[-c_i, c_i]``; for the 3-PPR (bearing, Eq. 17; the guide rhombus'
best vertex, Eq. 16; the revolute disk, Eq. 18, with ``n_i = +-E w_i``; tolerance intervals, Eq. 9)

.. math::

    c_i = \varepsilon_{\theta,i} \lvert l_i \rvert
        + \max\Bigl(\varepsilon_{g,i} \lvert H_{\sigma,i} \rvert,
                     \frac{2 \varepsilon_{g,i}}{L_{g,i}} \lvert H_{\gamma,i} \rvert\Bigr)
        + \varepsilon_{r,i} + \sum_q t_{q,i} \lvert H_{q,i} \rvert

(:meth:`~pmaccuracy.model.sources.ErrorSources.from_clearance_set` reads the
paper's clearance and tolerance formats into the chain's per-joint sources;
:func:`~pmaccuracy.model.sources.states_half_widths` gives ``c_i`` of any robot).
The set of pose errors is therefore the parallelepiped
``{A^-1 diag(c) t : t in [-1, 1]^3}``, a zonotope with three generators
``g_i = c_i A^-1[:, i]``. Then (Eq. 21, 22)

.. math::

    \Delta x_{\max} = \sum_i c_i \,\lvert (A^{-1})_{0i} \rvert \quad
    \text{(support function along } x \text{; likewise } y, \phi),
    \qquad
    \lVert \Delta p \rVert_{\max} = \max_{t \in \{\pm 1\}^3}
    \bigl\lVert \bigl(A^{-1} \operatorname{diag}(c)\, t\bigr)_{xy} \bigr\rVert

because a convex function (the norm) is maximal at a vertex and every vertex
of the projected zonotope is the projection of a vertex ``t``. The
maximizing configurations follow from the signs ``t``
(:func:`~pmaccuracy.model.sources.worst_configuration`).
:func:`slsqp_max_pose_errors` is the paper-style local baseline (on the paper's
own diagonals ``H_q``, Appendix A).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..model.clearances import ClearanceDisplacement, ClearanceSet
from .error_model import LINK_VARIATIONS, H_diagonals, PoseState, load_variations, pose_state
from .._display import html_table, summary, value_range
from ..errors import ConfigError
from ..model.manipulator import Manipulator, perp
from ..io.resolve import legs_values
from ..kinematics import DEFAULT_MAX_CONDITION, LIMIT_TOLERANCE, as_poses, check_within_limits
from ..io.resolve import clearances_arg, robot_arg
from ..kinematics import _raise_serial, _raise_singular, ik_from_states
from ..kinematics import leg_states
from ..kinematics import raw_transmission
from ..model import plausibility
from ..model.sources import (PPR_TOLERANCE_KEYS, ErrorSources, first_order_error, source_coefficient,
                              states_half_widths, worst_configuration)
from ..numerics.memory import settle_allocator
from ..numerics.screws import dot
from .error_model import VARIATION_UNITS

#: The four quantities of Eq. 21-22, in output order.
QUANTITIES = ("dx", "dy", "dphi", "dp")
#: Sign patterns t of the parallelepiped's vertices, one of each +-pair (t and -t give the same |dp|).
_VERTEX_SIGNS = np.array([[1, 1, 1], [1, 1, -1], [1, -1, 1], [1, -1, -1]], dtype=float)


def _sign(x: np.ndarray) -> np.ndarray:
    """sign with sign(0) = +1 (any choice attains the maximum when the coefficient vanishes)."""
    return np.where(x < 0, -1.0, 1.0)


@dataclass(frozen=True)
class PoseErrorBounds:
    """Maximum pose errors at a batch of poses (Eq. 21, 22); every array has the poses' leading shape ``(...)``.

    Attributes
    ----------
    poses : ``(..., 3)`` [mm, mm, rad]
    dx_max, dy_max, dp_max : ``(...)`` mm;  dphi_max : ``(...)`` rad
    half_widths : ``(..., 3)`` ``c_i``, bound of leg ``i``'s row of ``A [dp; dphi]`` (mm); with ``details``
    generators : ``(..., 3, 3)`` columns ``g_i = c_i A^-1[:, i]`` of the error zonotope; with ``details``
    dp_signs : ``(..., 3)`` the vertex ``t`` attaining ``dp_max``; with ``details``
    method : ``"exact"`` or ``"slsqp"``
    worst : per quantity (``dx, dy, dphi, dp``), the configuration attaining its maximum (with
        ``details=True``): for per-joint :class:`~pmaccuracy.model.sources.ErrorSources` (any architecture) a
        :class:`~pmaccuracy.model.sources.JointDisplacements` with arrays ``(..., 3 legs, 3 joints)``
        (:func:`~pmaccuracy.model.sources.worst_configuration` at ``worst_signs``), whose first-order pose
        error (:func:`~pmaccuracy.model.sources.first_order_error`) is ``+dx_max`` in x (likewise ``+dy_max``,
        ``+dphi_max``, and ``|(dx, dy)| = dp_max``); its negative attains the opposite extreme. For the
        3-PPR clearance format a :class:`~pmaccuracy.model.clearances.ClearanceDisplacement` (Eq. 16-18)
    worst_variations : maximizing parameter variations per quantity (3-PPR clearance format with
        ``tolerances``, ``details=True``)
    worst_signs : per quantity, the signs ``t_i`` ``(..., 3)`` of each leg's share ``e_i = t_i c_i`` at the
        maximum (per-joint sources of any architecture: each source then sits at its own extreme); with
        ``details`` (empty otherwise: only the four result arrays are built)
    """

    poses: np.ndarray
    dx_max: np.ndarray
    dy_max: np.ndarray
    dphi_max: np.ndarray
    dp_max: np.ndarray
    half_widths: np.ndarray | None = None
    generators: np.ndarray | None = None
    dp_signs: np.ndarray | None = None
    method: str = "exact"
    worst: dict[str, ClearanceDisplacement] = field(default_factory=dict)
    worst_variations: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    worst_signs: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def dphi_max_deg(self) -> np.ndarray:
        """``dphi_max`` in degrees."""
        return np.degrees(self.dphi_max)

    def __repr__(self) -> str:
        return summary("PoseErrorBounds", int(np.prod(self.poses.shape[:-1])), [
            f"dx_max {value_range(self.dx_max, 'mm')}", f"dy_max {value_range(self.dy_max, 'mm')}",
            f"dphi_max {value_range(self.dphi_max_deg, 'deg')}", f"dp_max {value_range(self.dp_max, 'mm')}"])

    def _repr_html_(self) -> str:
        return html_table("Maximum pose errors (mm, deg)", self.records())

    def records(self) -> list[dict]:
        """One dict per pose with the CLI's keys (mm, deg)."""
        poses = self.poses.reshape(-1, 3)
        cols = [a.reshape(-1) for a in (self.dx_max, self.dy_max, self.dphi_max_deg, self.dp_max)]
        return [{"x": float(p[0]), "y": float(p[1]), "phi_deg": float(np.degrees(p[2])),
                 "dx_max": float(a), "dy_max": float(b), "dphi_max_deg": float(c), "dp_max": float(d)}
                for p, a, b, c, d in zip(poses, *cols)]


def guide_shift(robot: Manipulator, H: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``H`` with ``H["shift"] = (E w_i) . (E u_i) = w_i . u_i``: the guide's lateral shift acts normal to the rail.

    The paper shifts the carriage along ``v_i`` (its ``delta d_i``, ``H_d``); that
    is the rail normal ``E u_i`` only when ``gamma_i = +-90 deg`` (both presets,
    which give identical numbers). Physically the play moves the carriage
    normal to the rail, whatever the offset's direction.
    """
    out = dict(H)
    out["shift"] = np.broadcast_to(np.sum(robot.w * robot.u, axis=-1), np.shape(H["theta"]))
    return out


def tolerances_arg(tolerances: Any, name: str = "tolerances") -> dict[str, np.ndarray] | None:
    """Tolerance half-widths ``{parameter: (3,)}`` (mm or rad) from a mapping, a preset name or a TOML path
    (:func:`load_tolerances`); ``None`` (or an empty mapping) stays as it is.

    Each value is a number (all three legs) or three numbers, finite and >= 0.
    """
    if tolerances is None:
        return None
    if isinstance(tolerances, (str, os.PathLike)):
        return load_tolerances(os.fspath(tolerances))
    if not isinstance(tolerances, Mapping):
        raise ConfigError(f"expected a mapping {{parameter: half-widths}}, a preset name or a TOML path, got "
                          f"{type(tolerances).__name__}", key=name)
    return {key: legs_values(value, f"{name}.{key}") for key, value in tolerances.items()}


def load_tolerances(spec: str) -> dict[str, np.ndarray]:
    """Tolerance half-widths from a variations TOML file or preset (see
    :func:`pmaccuracy.accuracy.error_model.load_variations`); negative or non-finite values are refused."""

    try:
        tolerances = _check_tolerances(load_variations(spec))
    except ConfigError as exc:
        if exc.source:
            raise
        raise ConfigError(exc.message, source=str(spec), key=exc.key) from None
    plausibility.warn(plausibility.tolerance_messages(tolerances, VARIATION_UNITS, str(spec)))
    return tolerances


def _check_tolerances(tolerances: Mapping[str, Any]) -> dict[str, np.ndarray]:
    out = {}
    for q, t in tolerances.items():
        if q not in LINK_VARIATIONS:
            raise ConfigError(f"unknown parameter {q!r}; tolerances apply to {', '.join(LINK_VARIATIONS)}",
                              key="tolerances")
        out[q] = legs_values(t, f"tolerances.{q}")  # 3 finite values >= 0 (ConfigError naming the key)
    return out


#: Poses per internal block: keeps every temporary in cache (measured 2.4x faster than one block).
CHUNK = 8192


def max_pose_errors(robot: Manipulator, clearances: ClearanceSet, poses: np.ndarray, *,
                    tolerances: Mapping[str, Any] | None = None, allow_outside: bool = False,
                    details: bool = False, max_condition: float = DEFAULT_MAX_CONDITION,
                    singular: str = "raise") -> PoseErrorBounds:
    """Exact ``dx_max, dy_max, dphi_max, dp_max`` at every pose (Eq. 21, 22), vectorized.

    Parameters
    ----------
    robot, clearances : objects, preset names or TOML paths (:mod:`pmaccuracy.io.resolve`)
    poses : ``(..., 3)`` [x mm, y mm, phi rad]
    tolerances : optional tolerance intervals on link parameters of a 3-PPR (manufacturing
        or assembly; also a preset name or TOML path of :func:`load_tolerances`),
        ``{name: half-widths (3,)}`` in mm/rad, e.g. ``{"theta":
        [1e-3] * 3, "d": [0.05] * 3}``: worst case over clearances and tolerances
        together (each becomes the chain's per-joint source of the same effect,
        :meth:`~pmaccuracy.model.sources.ErrorSources.from_clearance_set`); ``ClearanceSet()`` for
        tolerances alone (per-joint sources carry their tolerances themselves)
    allow_outside : evaluate poses outside the joint ranges too (otherwise
        :class:`~pmaccuracy.errors.OutsideJointLimitsError`)
    details : also return, per pose, the half-widths ``c``, the generators, the
        vertex attaining ``dp`` and the maximizing signs ``worst_signs`` of every
        quantity (any architecture; with :func:`pmaccuracy.model.sources.worst_configuration`
        they give the maximizing source values), and for the 3-PPR clearance format
        the maximizing clearance displacements ``.worst`` (each moves the platform by
        ``+dzeta_max`` in its quantity, its negative by ``-dzeta_max``) and, with
        ``tolerances``, the maximizing parameter variations ``.worst_variations``.
        Without it only the four result arrays are built (memory: 32 bytes a pose)
    singular : ``"raise"`` (default) or ``"nan"``: NaN at poses near a singularity instead of an error (with
        ``allow_outside``, also at poses some leg cannot reach at all, where the model is undefined)

    Notes
    -----
    Any architecture: each leg's half-width comes from its per-joint
    :class:`~pmaccuracy.model.sources.ErrorSources` paired with its constraint wrench
    (:func:`pmaccuracy.model.sources.states_half_widths`). A 3-PPR clearance set, with or
    without tolerances, takes the same path through
    :meth:`~pmaccuracy.model.sources.ErrorSources.from_clearance_set` (the same numbers as
    the paper's Eq. 19-22 on its diagonals ``H_q``, to rounding; ``tests/accuracy/test_one_engine.py``).

    Raises
    ------
    SingularPoseError : a pose at or near det A = 0 (condition number > ``max_condition``) or B_ii = 0
    OutsideJointLimitsError : a pose outside the joint ranges (unless ``allow_outside``)

    Example
    -------
    >>> b = max_pose_errors(Manipulator.preset("aalborg_3ppr"), ClearanceSet.load("case1"), [0.0, 0.0, 0.0])
    >>> round(float(b.dy_max), 6), round(float(b.dphi_max_deg), 4)
    (0.099851, 0.2202)
    """
    plausibility.check_orientations(poses, "poses", poses=True)
    robot = robot_arg(robot)  # preset names and files too; wrong types/shapes: ConfigError naming the parameter
    clearances = clearances_arg(clearances, robot)
    given_tolerances = tolerances
    tolerances = tolerances_arg(tolerances)
    if singular not in ("raise", "nan"):
        raise ConfigError(f"must be 'raise' or 'nan', got {singular!r}", key="singular")
    poses = as_poses(poses)
    flat = poses.reshape(-1, 3)
    per_joint = isinstance(clearances, ErrorSources)
    if per_joint:
        if tolerances:
            raise ConfigError("give tolerances per joint in the clearance file (position, direction, length) "
                              "for this robot", key="tolerances")
        sources = clearances.check(robot)
    else:
        robot.require_3ppr("the 3-PPR clearance format (guide, bearing, revolute per leg)")
        tolerances = _check_tolerances(tolerances or {})
        if tolerances and isinstance(given_tolerances, Mapping):   # a file's are checked by its reader
            plausibility.warn_caller(plausibility.tolerance_messages(tolerances, VARIATION_UNITS, "tolerances"))
        # the paper's clearances and link-parameter tolerances as the chain's per-joint sources: one engine
        sources = ErrorSources.from_clearance_set(clearances, tolerances).check(robot)
    result = _generic_bounds(robot, sources, poses, flat, allow_outside, details, max_condition, singular)
    if details and not per_joint:  # the paper's clearance displacements and variations at the same signs
        result = replace(result, **_paper_details(robot, clearances, sources, tolerances, result))
    elif details:                  # per-joint sources: each at its own extreme for the maximizing signs
        result = replace(result, worst=_joint_details(robot, sources, result))
    return result


def _joint_details(robot: Manipulator, sources: ErrorSources, result: PoseErrorBounds) -> dict:
    """``worst`` of per-joint sources: per quantity the :class:`~pmaccuracy.model.sources.JointDisplacements`
    ``(..., 3, 3)`` at the maximizing signs (:func:`~pmaccuracy.model.sources.worst_configuration`)."""
    lead = result.poses.shape[:-1]
    flat = result.poses.reshape(-1, 3)
    joints = ik_from_states(robot, leg_states(robot, flat)).joints
    out = {}
    for q, signs in result.worst_signs.items():
        config = worst_configuration(robot, sources, joints, flat, signs.reshape(-1, 3))
        out[q] = type(config)(*(getattr(config, f).reshape(lead + (3, 3)) for f in config.FIELDS))
    return out


def _paper_details(robot: Manipulator, clearances: ClearanceSet, sources: ErrorSources,
                   tolerances: dict[str, np.ndarray], result: PoseErrorBounds) -> dict:
    """``worst`` (the clearance displacements of Eq. 16-18) and ``worst_variations`` (the link-parameter
    variations of Eq. 9) of the per-joint configurations at the maximizing signs of each quantity
    (:func:`~pmaccuracy.model.sources.worst_configuration`, converted to the paper's variables)."""
    lead = result.poses.shape[:-1]
    flat = result.poses.reshape(-1, 3)
    states = leg_states(robot, flat)
    joints = ik_from_states(robot, states).joints
    worst, variations = {}, {}
    for q, signs in result.worst_signs.items():
        t = signs.reshape(-1, 3)
        config = worst_configuration(robot, sources, joints, flat, t)
        unit_f = np.stack([np.broadcast_to(st.f / np.abs(st.f), (flat.shape[0],)) for st in states], axis=-1)
        disp = ClearanceDisplacement(tau_b=config.tilt[:, :, 1], sigma_g=config.sigma[:, :, 0],
                                     tau_g=config.tau[:, :, 0],
                                     rho=np.broadcast_to(clearances.revolute_radial, t.shape).astype(float),
                                     varphi=np.angle(t * unit_f))
        worst[q] = ClearanceDisplacement(*(np.reshape(getattr(disp, f), lead + (3,))
                                           for f in ("tau_b", "sigma_g", "tau_g", "rho", "varphi")))
        if tolerances:
            values = {}
            for name, tol in tolerances.items():
                k, key = PPR_TOLERANCE_KEYS[name]
                coef = np.stack([np.broadcast_to(_coefficient(robot, i, k, key, st, flat, unit_f[:, i]),
                                                  (flat.shape[0],)) for i, st in enumerate(states)], axis=-1)
                values[name] = (t * tol * _sign(coef)).reshape(lead + (3,))
            variations[q] = values
    return {"worst": worst, "worst_variations": variations}


def _coefficient(robot: Manipulator, i: int, k: int, key: str, st, poses: np.ndarray,
                 unit_f: np.ndarray) -> np.ndarray:
    """Signed share of ``e_i`` per unit variation of a link parameter (the paper's ``H_q``, Appendix A, in the
    per-joint sources' sign convention): ``rho`` along ``n_i = E w_i`` (the leg's unit force ``unit_f`` is
    +-n_i), the others :func:`~pmaccuracy.model.sources.source_coefficient`."""
    if key == "position":                    # rho with n_i = E w_i (H_rho = +-1): its sign along the offset
        return dot(unit_f, 1j * complex(robot.w[i, 0], robot.w[i, 1]))
    return source_coefficient(robot.chains[i], k, key, st, poses)


@dataclass(frozen=True)
class _Block:
    """One block of :func:`bounds_kernel` (internal data of one evaluation)."""

    dx: np.ndarray
    dy: np.ndarray
    dphi: np.ndarray
    dp: np.ndarray
    within: np.ndarray
    reachable: np.ndarray
    condition: np.ndarray
    transmission: list   # each leg's unclipped index (kinematics.raw_transmission)
    states: tuple
    details: dict | None = None


def bounds_kernel(robot: Manipulator, sources, poses: np.ndarray, details: bool = False) -> _Block:
    """Exact maxima of one block of poses ``(n, 3)`` [mm, mm, rad] of any architecture, with no checks.

    The legs' rows ``r_i = [f_x, f_y, m_P]`` of ``A`` give the columns of
    ``A^-1`` as ``X_0 = r_1 x r_2, X_1 = r_2 x r_0, X_2 = r_0 x r_1`` over
    ``det A = r_0 . X_0``, so with the half-widths ``c_i``::

        dx = sum_i c_i |X_i,x| / |det A|      (likewise dy, dphi: Eq. 21)
        dp = max over t in {+-1}^3 of |sum_i t_i c_i (X_i,x, X_i,y)| / |det A|   (Eq. 22)

    Also returns the joint-limit mask ``within``, ``reachable``, the condition
    number of the homogenized ``A`` (:data:`~pmaccuracy.kinematics.DEFAULT_MAX_CONDITION`)
    and the legs' transmission indices, for the caller to refuse or blank poses.
    """

    settle_allocator()   # once a process: the blocks' temporaries stay on the heap from the first call on
    states = leg_states(robot, poses)
    n = poses.shape[0]
    within = np.ones(n, dtype=bool)
    reachable = np.ones(n, dtype=bool)
    for chain, st in zip(robot.chains, states):
        q0, q1, q2 = st.qs
        reachable &= np.isfinite(q0 + q1 + q2)
        for joint, qk in zip(chain.joints, st.qs):
            if joint.limited:
                within &= joint.within(qk, LIMIT_TOLERANCE)
    within &= reachable
    (a0, b0, c0), (a1, b1, c1), (a2, b2, c2) = [(np.real(st.f), np.imag(st.f), st.m_P) for st in states]
    X = ((b1 * c2 - c1 * b2, c1 * a2 - a1 * c2, a1 * b2 - b1 * a2),
         (b2 * c0 - c2 * b0, c2 * a0 - a2 * c0, a2 * b0 - b2 * a0),
         (b0 * c1 - c0 * b1, c0 * a1 - a0 * c1, a0 * b1 - b0 * a1))
    det = a0 * X[0][0] + b0 * X[0][1] + c0 * X[0][2]
    L = robot.characteristic_length
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv_abs_det = 1.0 / np.abs(det)
        abs_X = [[np.abs(v) for v in col] for col in X]
        norm_A = np.maximum(np.maximum(np.abs(a0) + np.abs(a1) + np.abs(a2), np.abs(b0) + np.abs(b1) + np.abs(b2)),
                            (np.abs(c0) + np.abs(c1) + np.abs(c2)) / L)
        norm_inv = np.maximum(np.maximum(abs_X[0][0] + abs_X[0][1] + L * abs_X[0][2],
                                         abs_X[1][0] + abs_X[1][1] + L * abs_X[1][2]),
                              abs_X[2][0] + abs_X[2][1] + L * abs_X[2][2])
        cond = norm_A * norm_inv * inv_abs_det
        cond = np.where(np.isfinite(cond), cond, np.inf)
    trans = raw_transmission(robot, states)
    c = states_half_widths(robot, sources, states, poses)
    with np.errstate(invalid="ignore", over="ignore"):
        w = [c[:, i] * inv_abs_det for i in range(3)]
        dx = np.broadcast_to(w[0] * abs_X[0][0] + w[1] * abs_X[1][0] + w[2] * abs_X[2][0], (n,))
        dy = w[0] * abs_X[0][1] + w[1] * abs_X[1][1] + w[2] * abs_X[2][1]
        dphi = w[0] * abs_X[0][2] + w[1] * abs_X[1][2] + w[2] * abs_X[2][2]
        gx = [w[i] * X[i][0] for i in range(3)]
        gy = [w[i] * X[i][1] for i in range(3)]
        sx, sy = gx[0] + gx[1], gy[0] + gy[1]
        ex, ey = gx[0] - gx[1], gy[0] - gy[1]
        norms2 = ((sx + gx[2]) ** 2 + (sy + gy[2]) ** 2, (sx - gx[2]) ** 2 + (sy - gy[2]) ** 2,
                  (ex + gx[2]) ** 2 + (ey + gy[2]) ** 2, (ex - gx[2]) ** 2 + (ey - gy[2]) ** 2)
        dp = np.sqrt(np.maximum(np.maximum(norms2[0], norms2[1]), np.maximum(norms2[2], norms2[3])))
    extra = None
    if details:
        with np.errstate(divide="ignore", invalid="ignore"):
            A_inv = np.stack([np.stack(np.broadcast_arrays(*col, np.empty(n))[:3], axis=-1) for col in X],
                             axis=-1) / np.broadcast_to(det, (n,))[:, None, None]
        best = np.argmax(np.stack(np.broadcast_arrays(*norms2, np.empty(n))[:4], axis=-1), axis=-1)
        extra = {"c": c, "G": A_inv * c[:, None, :], "t": _VERTEX_SIGNS[best],  # (norms2 may hold scalars)
                 "s_dx": _sign(A_inv[:, 0, :]), "s_dy": _sign(A_inv[:, 1, :]), "s_dphi": _sign(A_inv[:, 2, :]),
                 "s_dp": _VERTEX_SIGNS[best]}
    dy, dphi, dp, cond = (np.broadcast_to(v, (n,)) for v in (dy, dphi, dp, cond))
    return _Block(dx=dx, dy=dy, dphi=dphi, dp=dp, within=within, reachable=reachable, condition=cond,
                  transmission=trans, states=states, details=extra)


def _regular(block: _Block, max_condition: float) -> np.ndarray:
    ok = block.condition <= max_condition
    for t in block.transmission:            # NaN (undefined) compares False: not regular
        ok = ok & (t >= 1.0 / max_condition)
    return ok


def _refuse(robot: Manipulator, poses: np.ndarray, block: _Block, allow_outside: bool, max_condition: float,
            singular: str) -> np.ndarray:
    """Raise for the first pose outside the ranges (unless allowed) or singular (``singular="raise"``);
    returns the mask of regular poses (a pose some leg cannot reach at all is not regular: NaN, with
    ``allow_outside`` and ``singular="nan"``)."""

    if not np.all(block.reachable) and not (allow_outside and singular == "nan"):
        check_within_limits(robot, poses, ik_from_states(robot, block.states))   # no model at all there
    regular = _regular(block, max_condition) & np.broadcast_to(block.reachable, block.condition.shape)
    if singular == "raise" and not np.all(regular):
        ok = block.condition <= max_condition
        if not np.all(ok):
            _raise_singular(robot, poses, ok, block.condition, max_condition)
        trans = np.stack([np.broadcast_to(t, block.condition.shape) for t in block.transmission], axis=-1)
        _raise_serial(poses, np.where(np.isfinite(trans), np.minimum(trans, 1.0), 0.0), max_condition)
    if not allow_outside and not np.all(block.within):
        check_within_limits(robot, poses, ik_from_states(robot, block.states))
    return regular


def _generic_bounds(robot: Manipulator, sources, poses: np.ndarray, flat: np.ndarray, allow_outside: bool,
                    details: bool, max_condition: float, singular: str) -> PoseErrorBounds:
    """:func:`max_pose_errors` of any architecture: results preallocated and filled block by block."""
    lead = poses.shape[:-1]
    n = flat.shape[0]
    res = {q: np.empty(n) for q in QUANTITIES}
    shapes = {"c": (3,), "G": (3, 3), "t": (3,), **{f"s_{q}": (3,) for q in QUANTITIES}}
    extra = {k: np.empty((n,) + tail) for k, tail in shapes.items()} if details else {}
    for k in range(0, n, CHUNK):
        block_poses = flat[k:k + CHUNK]
        block = bounds_kernel(robot, sources, block_poses, details)
        regular = _refuse(robot, block_poses, block, allow_outside, max_condition, singular)
        every = bool(np.all(regular))
        for q in QUANTITIES:
            res[q][k:k + CHUNK] = getattr(block, q) if every else np.where(regular, getattr(block, q), np.nan)
        for key, arr in extra.items():
            value = block.details[key]
            # the generators are NaN where the pose is not regular; half-widths and signs are kept
            arr[k:k + CHUNK] = np.where(regular[:, None, None], value, np.nan) if key == "G" else value
    shaped = lambda a, tail=(): a.reshape(lead + tail)  # noqa: E731
    return PoseErrorBounds(poses=poses, dx_max=shaped(res["dx"]), dy_max=shaped(res["dy"]),
                           dphi_max=shaped(res["dphi"]), dp_max=shaped(res["dp"]),
                           half_widths=shaped(extra["c"], (3,)) if details else None,
                           generators=shaped(extra["G"], (3, 3)) if details else None,
                           dp_signs=shaped(extra["t"], (3,)) if details else None, method="exact",
                           worst_signs={q: shaped(extra[f"s_{q}"], (3,)) for q in QUANTITIES} if details else {})


#: Poses per kernel call of :func:`bounds_or_nan` at most: a map's band (about 10^4 grid points) goes to the
#: kernel whole, longer inputs in equal pieces (a piece of 8192 and one of 1808 cost a third more than one of
#: 10000: the kernel's fixed cost per call is about that of 2000 poses).
BAND = 2 * CHUNK


def bounds_or_nan(robot: Manipulator, clearances, poses: np.ndarray,
                  max_condition: float = DEFAULT_MAX_CONDITION, out=None) -> np.ndarray:
    """``(n, 4)`` [dx_max mm, dy_max mm, dphi_max deg, dp_max mm] at poses ``(n, 3)``, NaN outside the joint
    ranges or near a singularity (one pass: the maps' kernel; no error is raised).

    ``out``: four arrays ``(n,)`` (or of any shape of ``n`` elements, C-contiguous) to write the four
    quantities straight into, e.g. a map's final arrays; they are returned instead of a new ``(n, 4)``."""

    robot = robot_arg(robot)
    clearances = clearances_arg(clearances, robot)
    sources = clearances if isinstance(clearances, ErrorSources) else ErrorSources.from_clearance_set(clearances)
    n = poses.shape[0]
    if out is None:
        result = np.empty((n, 4))
        targets = [result[:, v] for v in range(4)]
    else:
        result = out
        targets = []
        for target in out:
            if target.size != n or not target.flags.c_contiguous:
                raise ValueError(f"out: four C-contiguous arrays of {n} elements expected")
            targets.append(target.reshape(-1))            # a view (contiguous)
    pieces = -(-n // BAND)
    size = -(-n // max(1, pieces))
    for k in range(0, n, max(1, size)):
        block = bounds_kernel(robot, sources, poses[k:k + size])
        ok = block.within & _regular(block, max_condition)
        bad = None if ok.all() else ~ok
        for target, value in zip(targets, (block.dx, block.dy, block.dphi, block.dp)):
            dst = target[k:k + size]
            if value is block.dphi:
                np.degrees(value, out=dst)
            else:
                dst[...] = value
            if bad is not None:
                dst[bad] = np.nan
    return result


def first_order_pose_error(robot: Manipulator, poses: np.ndarray | PoseState,
                           displacement: ClearanceDisplacement) -> np.ndarray:
    """Pose error ``J^c_err delta^c`` (Eq. 19, 20) for given clearance displacements, ``(..., 3)`` [mm, mm, rad].

    The displacements become the 3-PPR chain's per-joint values
    (:meth:`~pmaccuracy.model.clearances.ClearanceDisplacement.to_joint_displacements`), paired with each
    leg's wrench (:func:`pmaccuracy.model.sources.first_order_error`).
    """
    state = poses if isinstance(poses, PoseState) else pose_state(robot, poses)
    return first_order_error(robot, state.joints, state.poses, displacement.to_joint_displacements())


# ----------------------------------------------------------------------------- baseline
def _leg_coefficients(clearances: ClearanceSet, state: PoseState, H: dict[str, np.ndarray], index: int
                      ) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Columns of the paper's J^c_err (Eq. 20a) at one pose, scaled to unit-box variables.

    Variables (normalized): zb_i = dtau_b,i / eps_theta,i; zs_i = dsigma_g,i / eps_g,i;
    zt_i = dtau_g,i / (2 eps_g,i / L_g,i) (the rhombus becomes |zs +- zt| <= 1);
    zr_i = drho_i / eps_r,i in [0, 1] with angle varphi_i. Variables whose
    clearance is zero are left out. ``H`` holds the diagonals at every pose of ``state``.
    """
    A_inv = state.A_inv[index]
    cols, kinds, legs = [], [], []
    eps_b, eps_g, eps_r = clearances.bearing_angle, clearances.guide_lateral, clearances.revolute_radial
    L = clearances.guide_block_length
    for i in range(3):
        if eps_b[i] > 0:
            cols.append(A_inv[:, i] * H["theta"][index, i] * eps_b[i]); kinds.append("b"); legs.append(i)
        if eps_g[i] > 0:
            cols.append(A_inv[:, i] * H["shift"][index, i] * eps_g[i]); kinds.append("s"); legs.append(i)
            cols.append(A_inv[:, i] * H["gamma"][index, i] * 2 * eps_g[i] / L[i]); kinds.append("t"); legs.append(i)
        if eps_r[i] > 0:
            cols.append(A_inv[:, i] * eps_r[i]); kinds.append("r"); legs.append(i)
    return (np.array(cols).T if cols else np.zeros((3, 0))), kinds, np.array(legs, dtype=int)


def slsqp_max_pose_errors(robot: Manipulator, clearances: ClearanceSet, poses: np.ndarray, *,
                          n_starts: int = 6, seed: int = 0, allow_outside: bool = False,
                          max_condition: float = DEFAULT_MAX_CONDITION) -> PoseErrorBounds:
    """The paper's local-optimization baseline (Eq. 21, 22), solved pose by pose with SLSQP.

    Variables are those of Eq. 20b plus the revolute directions varphi_i:
    dtau_b, dsigma_g, dtau_g, drho in [0, eps_r] and varphi in [0, 2 pi], with the
    rhombus (Eq. 16a, 16b) as linear inequalities. Like fmincon in the paper it
    is local: it is restarted from ``n_starts`` seeded random feasible points
    and the best is kept. Variables are scaled to unit boxes for conditioning,
    and the optimizer's final point is projected back onto the constraints
    before it is evaluated, so every reported value is attainable.

    This is a baseline for cross-checks and benchmarks, orders of magnitude
    slower than :func:`max_pose_errors`, and never above it (to rounding).
    """

    robot = robot_arg(robot)
    clearances = clearances_arg(clearances, robot)
    poses = as_poses(poses)
    flat = poses.reshape(-1, 3)
    state = pose_state(robot, flat, max_condition)
    if not allow_outside:
        check_within_limits(robot, flat, state)
    rng = np.random.default_rng(seed)
    Ew = perp(robot.w)
    out = np.zeros((flat.shape[0], 4))
    H = guide_shift(robot, H_diagonals(robot, state))
    for k in range(flat.shape[0]):
        C, kinds, legs = _leg_coefficients(clearances, state, H, k)
        out[k] = _slsqp_pose(C, kinds, legs, Ew, n_starts, rng)
    shape = poses.shape[:-1]
    return PoseErrorBounds(poses=poses, dx_max=out[:, 0].reshape(shape), dy_max=out[:, 1].reshape(shape),
                           dphi_max=out[:, 2].reshape(shape), dp_max=out[:, 3].reshape(shape), method="slsqp")


def _slsqp_pose(C: np.ndarray, kinds: list[str], legs: np.ndarray, Ew: np.ndarray, n_starts: int,
                rng: np.random.Generator) -> np.ndarray:
    """Best local maxima of the four problems at one pose: returns [dx, dy, dphi, dp]."""
    from scipy.optimize import minimize  # only the baseline needs it (keeps the CLI's start-up short)

    m = C.shape[1]
    if m == 0:
        return np.zeros(4)
    kinds_arr = np.array(kinds)
    rev = np.flatnonzero(kinds_arr == "r")
    n_var = m + rev.size  # normalized amplitudes, then one angle per revolute joint
    # Unit-box bounds; revolute amplitude drho in [0, 1] (Eq. 18), angles in [0, 2 pi].
    bounds = [(0.0, 1.0) if kd == "r" else (-1.0, 1.0) for kd in kinds] + [(0.0, 2 * np.pi)] * rev.size
    # Rhombus |zs + zt| <= 1 and |zs - zt| <= 1 as four linear inequalities per guide (Eq. 16).
    pairs = [(j, j + 1) for j, kd in enumerate(kinds) if kd == "s"]
    A_ineq = []
    for js, jt in pairs:
        for a, b in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            row = np.zeros(n_var); row[js] = -a; row[jt] = -b  # 1 - (a zs + b zt) >= 0
            A_ineq.append(row)
    A_ineq = np.array(A_ineq) if A_ineq else np.zeros((0, n_var))
    constraints = [{"type": "ineq", "fun": lambda z: 1.0 + A_ineq @ z, "jac": lambda z: A_ineq}] if pairs else []
    # H_rho,i = (E w_i)^T vec(varphi_i): the revolute term's weight depends on its angle.
    rev_normals = Ew[legs[rev]] if rev.size else np.zeros((0, 2))

    def effect(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose error (3,) and its Jacobian w.r.t. z (3, n_var)."""
        weights = np.ones(m)
        dweights = np.zeros(rev.size)
        if rev.size:
            ang = z[m:]
            weights[rev] = rev_normals[:, 0] * np.cos(ang) + rev_normals[:, 1] * np.sin(ang)
            dweights = -rev_normals[:, 0] * np.sin(ang) + rev_normals[:, 1] * np.cos(ang)
        amp = z[:m]
        e = C @ (weights * amp)
        jac = np.zeros((3, n_var))
        jac[:, :m] = C * weights
        if rev.size:
            jac[:, m:] = C[:, rev] * (amp[rev] * dweights)
        return e, jac

    def project(z: np.ndarray) -> np.ndarray:
        z = np.clip(z, [b[0] for b in bounds], [b[1] for b in bounds])
        for js, jt in pairs:
            p, q = np.clip(z[js] + z[jt], -1, 1), np.clip(z[js] - z[jt], -1, 1)
            z[js], z[jt] = (p + q) / 2, (p - q) / 2
        return z

    def start() -> np.ndarray:
        z = np.array([rng.uniform(lo, hi) for lo, hi in bounds])
        return project(z)

    results = np.zeros(4)
    for qi, rows in enumerate(([0], [1], [2], [0, 1])):
        scale = max(float(np.linalg.norm(C[rows])), 1e-300)

        def objective(z: np.ndarray, rows=rows, scale=scale) -> tuple[float, np.ndarray]:
            e, jac = effect(z)
            val = e[rows] / scale
            return -float(val @ val), -2.0 * (val @ jac[rows]) / scale

        best = 0.0
        for _ in range(n_starts):
            res = minimize(objective, start(), jac=True, method="SLSQP", bounds=bounds,
                           constraints=constraints, options={"ftol": 1e-14, "maxiter": 200})
            e, _ = effect(project(res.x.copy()))
            best = max(best, float(np.linalg.norm(e[rows])))
        results[qi] = best
    return results
