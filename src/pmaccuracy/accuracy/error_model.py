r"""First-order error model: sensitivity Jacobians of the pose (paper Sec. 4.1, Eq. 6-15, Appendix A).

Differentiating the loop closure Eq. 1 of leg ``i`` (Eq. 6)::

    dp = da h + a dalpha E h + ds u + s dbeta' E u + dd v + d dgamma' E v
         + dl w + l dtheta' E w + drho n + dr k + r (dphi + dpsi) E k

with ``dbeta' = dalpha + dbeta``, ``dgamma' = dbeta' + dgamma``,
``dtheta' = dgamma' + dtheta`` (Eq. 7). Dotting with ``E w_i`` removes the idle
passive-joint variation ``dl_i`` (``w^T E^T w = 0``, ``w^T E^T E w = 1``), giving
one scalar equation per leg (Eq. 8)::

    A [dp; dphi] = sum_q diag(H_q) dq,        q in {a, alpha, s, beta, d, gamma, theta, rho, r, psi}

.. math::

    A \begin{bmatrix} \delta p \\ \delta\phi \end{bmatrix} = \sum_q \operatorname{diag}(H_q)\, \delta q,
    \qquad
    \begin{bmatrix} \delta x \\ \delta y \\ \delta\phi \end{bmatrix} = \sum_q J_q\, \delta q,
    \quad J_q = A^{-1} H_q \quad \text{(Eq. 8, 10, 11)}

where ``A`` is the forward Jacobian (Eq. 4a), ``H_s = B`` (Eq. 4b) and the other
diagonals are (Appendix A, Eq. A-1a..A-1i)::

    H_a     = w^T E^T h                  H_d     = w^T E^T v
    H_alpha = w^T (a h + s u + d v) + l  H_gamma = d w^T v + l
    H_beta  = w^T (s u + d v) + l        H_theta = l
    H_rho   = w^T E^T n                  H_r     = w^T E^T k
    H_psi   = r w^T k

so that ``J_q = A^-1 H_q`` (Eq. 11) and the pose error is
``[dx, dy, dphi] = sum_q J_q dq`` (Eq. 10). Every column ``i`` of every ``J_q``
is a multiple of column ``i`` of ``A^-1``: this is what makes the worst-case
problems of :mod:`pmaccuracy.accuracy.bounds` exactly solvable.

The text of Eq. 9, 10, 13 and 20b is garbled in the available copy; everything
here is derived from Eq. 6-8 and checked against finite differences of the
exact model (``tests/accuracy/test_error_model.py``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..model import _tomlio
from ..errors import ConfigError
from ..model.manipulator import Manipulator, perp, unit
from ..kinematics import DEFAULT_MAX_CONDITION, as_poses, inverse_kinematics, regular_inverse
from ..io.resolve import robot_arg

#: Variations of the link-parameter form (Eq. 10), in column order of :func:`error_jacobian`.
LINK_VARIATIONS = ("a", "alpha", "s", "beta", "d", "gamma", "theta", "rho", "r", "psi")
#: Units of each variation (mm or rad).
VARIATION_UNITS = {"a": "mm", "alpha": "rad", "s": "mm", "beta": "rad", "d": "mm", "gamma": "rad",
                   "theta": "rad", "rho": "mm", "r": "mm", "psi": "rad"}
#: Blocks of the Cartesian joint-point form (Eq. 13, 15a), in column order.
CARTESIAN_BLOCKS = ("s", "theta", "rho", "A", "B", "C", "D")


@dataclass(frozen=True)
class PoseState:
    """Everything the error model needs at a batch of poses (shapes ``(N, ...)``).

    poses (N, 3) [mm, mm, rad]; s, l (N, 3) joint values (mm) and
    within_limits (N,) from the inverse kinematics (Eq. 2); k (N, 3, 2)
    platform directions; A, B (N, 3, 3) Jacobians (Eq. 4); A_inv (N, 3, 3).
    """

    poses: np.ndarray
    s: np.ndarray
    l: np.ndarray
    within_limits: np.ndarray
    k: np.ndarray
    A: np.ndarray
    B: np.ndarray
    A_inv: np.ndarray
    joints: np.ndarray | None = None


def pose_state(robot: Manipulator, poses: np.ndarray, max_condition: float = DEFAULT_MAX_CONDITION) -> PoseState:
    """Joint values and Jacobians at ``poses`` ``(..., 3)``.

    Raises :class:`~pmaccuracy.errors.SingularPoseError` for poses near det A = 0
    (joint limits are not checked here: see :func:`pmaccuracy.kinematics.check_within_limits`).
    The returned arrays keep the leading shape of ``poses``.
    """
    poses = as_poses(poses)
    robot.require_3ppr("the paper's error model")
    ik = inverse_kinematics(robot, poses)
    A, B = ik.A, ik.B
    A_inv = regular_inverse(robot, A, poses, max_condition)
    k = unit(poses[..., None, 2] + robot.psi)
    return PoseState(poses=poses, s=ik.s, l=ik.l, within_limits=ik.within_limits, k=k, A=A, B=B, A_inv=A_inv,
                     joints=ik.joints)


def _state(robot: Manipulator, poses_or_state: np.ndarray | PoseState) -> PoseState:
    return poses_or_state if isinstance(poses_or_state, PoseState) else pose_state(robot, poses_or_state)


def H_diagonals(robot: Manipulator, poses: np.ndarray | PoseState,
                varphi: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Diagonals of every ``H_q`` (Appendix A), each of shape ``(..., 3)``.

    Units: ``H_a, H_s, H_d, H_rho, H_r`` are dimensionless (they multiply mm
    variations); ``H_alpha, H_beta, H_gamma, H_theta, H_psi`` are in mm (they
    multiply rad variations).

    Parameters
    ----------
    varphi : ``(..., 3)`` rad, optional
        Directions ``n_i = vec(varphi_i)`` of the revolute clearance displacement
        (Eq. 18). Default: ``n_i = E w_i``, the direction that moves the platform
        most (``H_rho = 1``); the component of ``n_i`` along ``w_i`` is taken up
        by the passive joint and has no effect.
    """
    st = _state(robot, poses)
    w, h, u, v = robot.w, robot.h, robot.u, robot.v
    Ew = perp(w)
    s, l = st.s, st.l
    dot = lambda x, y: np.sum(x * y, axis=-1)  # noqa: E731
    w_su_dv = s * dot(w, u) + robot.d * dot(w, v)  # w^T (s u + d v)
    if varphi is None:
        H_rho = np.ones_like(s)
    else:
        H_rho = dot(Ew, unit(np.asarray(varphi, dtype=float)))
    return {
        "a": np.broadcast_to(dot(Ew, h), s.shape),
        "alpha": robot.a * dot(w, h) + w_su_dv + l,
        "s": np.broadcast_to(dot(Ew, u), s.shape),
        "beta": w_su_dv + l,
        "d": np.broadcast_to(dot(Ew, v), s.shape),
        "gamma": robot.d * dot(w, v) + l,
        "theta": l,
        "rho": np.broadcast_to(H_rho, s.shape),
        "r": dot(Ew, st.k),
        "psi": robot.r * dot(w, st.k),
    }


def sensitivity_jacobians(robot: Manipulator, poses: np.ndarray | PoseState,
                          varphi: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """``J_q = A^-1 diag(H_q)`` (Eq. 11) for every q in :data:`LINK_VARIATIONS`, each ``(..., 3, 3)``.

    ``J_s`` is the kinematic Jacobian ``J = A^-1 B`` (Eq. 5). Rows are
    ``[dx (mm), dy (mm), dphi (rad)]``; column ``i`` is leg ``i``'s variation.
    """
    st = _state(robot, poses)
    H = H_diagonals(robot, st, varphi)
    return {q: st.A_inv * H[q][..., None, :] for q in LINK_VARIATIONS}


def error_jacobian(robot: Manipulator, poses: np.ndarray | PoseState, form: str = "link",
                   varphi: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
    """The global sensitivity Jacobian ``J_err`` and the names of its columns.

    ``form="link"`` (Eq. 10): ``[J_a J_alpha J J_beta J_d J_gamma J_theta J_rho J_r J_psi]``,
    shape ``(..., 3, 30)``, columns named ``"alpha2"`` etc.

    ``form="cartesian"`` (Eq. 13-15): ``[J J_theta J_rho J_A J_B J_C J_D]``,
    shape ``(..., 3, 33)``, see :func:`cartesian_jacobians` for the meaning of
    the point displacements.
    """
    st = _state(robot, poses)
    if form == "link":
        J = sensitivity_jacobians(robot, st, varphi)
        names = [f"{q}{i}" for q in LINK_VARIATIONS for i in (1, 2, 3)]
        return np.concatenate([J[q] for q in LINK_VARIATIONS], axis=-1), names
    if form == "cartesian":
        blocks = cartesian_jacobians(robot, st, varphi)
        names = [f"{q}{i}" for q in ("s", "theta", "rho") for i in (1, 2, 3)]
        names += [f"{p}{i}{ax}" for p in "ABCD" for i in (1, 2, 3) for ax in "xy"]
        return np.concatenate([blocks[b] for b in CARTESIAN_BLOCKS], axis=-1), names
    raise ValueError(f"form must be 'link' or 'cartesian', got {form!r}")


def cartesian_jacobians(robot: Manipulator, poses: np.ndarray | PoseState,
                        varphi: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Sensitivities to Cartesian displacements of the joint points (Eq. 12-13, A-2a..A-2d).

    Each pair of link parameters (length, angle) of a link is traded for the
    displacement of the link's end point, expressed in the frame of the link
    it is attached to (Eq. 12)::

        dA_i = [h_i, a_i E h_i] [da_i; dalpha_i]                 A_i in the base frame
        dB_i = [u'_i, s_i E u'_i] [ds_i; dbeta_i]                B_i - A_i in the frame of h_i
        dC_i = [v'_i, d_i E v'_i] [dd_i; dgamma_i]               C_i - B_i in the frame of u_i
        dD_i = -[k'_i, r_i E k'_i] [dr_i; dpsi_i]                D_i - P in the platform frame

    with ``u' = vec(beta)``, ``v' = vec(gamma)``, ``k' = vec(psi)``. Hence
    ``J_A = [J_a J_alpha] [A_a A_alpha]^-1`` and so on (Appendix A-2). As in
    the paper, the actuated part of ``dB_i`` (along ``u_i``) is left to the
    ``J ds`` term: ``J_B = [0 J_beta] [B_s B_beta]^-1``. ``dD_i`` is the
    displacement of the revolute centre ``D_i`` in the platform frame (the
    paper's garbled A-2d leaves its sign open).

    Each block is ``(..., 3, 6)`` with columns ``[1x, 1y, 2x, 2y, 3x, 3y]``; keys
    ``"s", "theta", "rho"`` hold the ``(..., 3, 3)`` blocks of Eq. 13.
    Where the 2x2 map is singular (``s_i = 0`` for B, ``d_i = 0`` for C,
    ``a_i = 0`` for A) the point displacement cannot produce the angle change
    and the block's two columns for that leg are NaN.
    """
    st = _state(robot, poses)
    J = sensitivity_jacobians(robot, st, varphi)
    shape = st.s.shape

    def block(J_len: np.ndarray | None, J_ang: np.ndarray, frame_angle: np.ndarray, length: np.ndarray,
              sign: float = 1.0) -> np.ndarray:
        # Per leg: [dlen; dang] = M^-1 dP, M = sign [e, length E e], e = vec(frame_angle).
        # M^-1 = sign [e^T; (E e)^T / length] since e and E e are orthonormal.
        e = np.broadcast_to(unit(frame_angle), shape + (2,))
        Ee = perp(e)
        length = np.broadcast_to(length, shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_len = np.where(np.abs(length) > 1e-12, 1.0 / length, np.nan)
        out = np.empty(shape[:-1] + (3, 6))
        for i in range(3):
            col_len = J_len[..., :, i, None] * e[..., i, None, :] if J_len is not None else 0.0
            col_ang = J_ang[..., :, i, None] * (Ee[..., i, None, :] * inv_len[..., i, None, None])
            out[..., :, 2 * i:2 * i + 2] = sign * (col_len + col_ang)
        return out

    return {
        "s": J["s"],
        "theta": J["theta"],
        "rho": J["rho"],
        "A": block(J["a"], J["alpha"], robot.alpha, robot.a),
        "B": block(None, J["beta"], robot.beta, st.s),
        "C": block(J["d"], J["gamma"], robot.gamma, robot.d),
        "D": block(J["r"], J["psi"], robot.psi, robot.r, sign=-1.0),
    }


def pose_error(robot: Manipulator, poses: np.ndarray | PoseState,
               variations: Mapping[str, Any], varphi: np.ndarray | None = None) -> np.ndarray:
    """First-order pose error ``[dx, dy, dphi]`` (mm, mm, rad) for parameter variations (Eq. 10, 14).

    ``variations`` maps names of :data:`LINK_VARIATIONS` to per-leg values of
    shape ``(3,)`` or ``(..., 3)`` (mm or rad), e.g. the assembly errors of
    Table 2 (:func:`assembly_errors`), or a preset name / TOML path of
    :func:`load_variations`; ``robot`` may be a preset name or a TOML path. Returns ``(..., 3)``.
    """
    import os


    robot = robot_arg(robot)
    if isinstance(variations, (str, os.PathLike)):
        variations = load_variations(variations)
    if not isinstance(variations, Mapping):
        raise ConfigError(f"expected a mapping {{parameter: per-leg values}}, a preset name or a TOML path, got "
                          f"{type(variations).__name__}", key="variations")
    unknown = set(variations) - set(LINK_VARIATIONS)
    if unknown:
        raise ConfigError(f"unknown variations {sorted(unknown)}; expected some of {LINK_VARIATIONS}",
                          key="variations")
    for q, dq in variations.items():
        try:
            arr = np.asarray(dq, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(f"expected numbers, got {dq!r}", key=f"variations.{q}") from None
        if arr.ndim and arr.shape[-1] != 3 or not np.all(np.isfinite(arr)):
            raise ConfigError(f"expected finite values of shape (3,) or (..., 3) (one per leg), got shape "
                              f"{arr.shape}", key=f"variations.{q}")
    st = _state(robot, poses)
    H = H_diagonals(robot, st, varphi)
    # A [dx dy dphi]^T = sum_q H_q dq  (Eq. 9), solved once for all q.
    rhs = sum(H[q] * np.asarray(dq, dtype=float) for q, dq in variations.items())
    rhs = np.broadcast_to(rhs, st.s.shape)
    return np.einsum("...ij,...j->...i", st.A_inv, rhs)


# ---------------------------------------------------------------------------- assembly errors
#: Keys of a variations file: the variation name and its unit.
_VARIATION_KEYS = {f"{q}_{VARIATION_UNITS[q]}": q for q in LINK_VARIATIONS if q not in ("s", "rho")}


def load_variations(spec: str | Path) -> dict[str, np.ndarray]:
    """Per-leg parameter variations from a TOML file or a preset (``aalborg_table2``).

    Format: three ``[[legs]]`` tables with keys ``<name>_<unit>``, e.g.
    ``beta_rad = 0.014``, ``d_mm = -0.08`` (any of a_mm, alpha_rad, beta_rad,
    d_mm, gamma_rad, theta_rad, r_mm, psi_rad; missing keys are 0).
    Returns ``{name: (3,) array}`` in mm and rad.
    """
    data, source = _tomlio.read_spec(spec, kind="variations", folder="variations")
    _tomlio.reject_unknown(data, {"name", "description", "legs"}, source=source, where="")
    out = {q: np.zeros(3) for q in _VARIATION_KEYS.values()}
    for i, table in enumerate(_tomlio.legs_table(data, source=source)):
        _tomlio.reject_unknown(table, set(_VARIATION_KEYS), source=source, where=f"legs[{i + 1}]")
        for key, q in _VARIATION_KEYS.items():
            out[q][i] = _tomlio.number(table, key, source=source, where=f"legs[{i + 1}]", default=0.0)
    return {q: v for q, v in out.items() if np.any(v != 0)}


def assembly_errors() -> dict[str, np.ndarray]:
    """The assembly errors measured on the prototype (paper Table 2): beta, gamma, theta (rad), d (mm)."""
    return load_variations("aalborg_table2")


__all__ = ["CARTESIAN_BLOCKS", "H_diagonals", "LINK_VARIATIONS", "PoseState", "VARIATION_UNITS",
           "assembly_errors", "cartesian_jacobians", "error_jacobian", "load_variations", "pose_error",
           "pose_state", "sensitivity_jacobians"]
