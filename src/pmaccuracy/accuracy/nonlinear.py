"""Virtual prototype: the exact (nonlinear) loop closure with errors and clearance displacements.

The first-order model of :mod:`pmaccuracy.accuracy.error_model` and :mod:`pmaccuracy.accuracy.bounds`
linearizes Eq. 1. Here the perturbed chain of every leg is closed exactly with
the actuators locked at their nominal values ``s_i``::

    p = a'_i h'_i + (s_i + ds_i) u'_i + dsigma_g,i E u'_i + d'_i v''_i + l_i w''_i + drho_i n_i + r'_i vec(phi + psi'_i)

where primes are the varied link parameters (Eq. 6), ``v''`` carries the guide
tilt ``dtau_g`` and ``w''`` the guide and bearing tilts ``dtau_g + dtau_b``
(Sec. 4.2). The pose is solved analytically by
:func:`pmaccuracy.kinematics.solve_loop_closure` (the assembly mode nearest to
the nominal pose is kept). The difference from the first-order prediction is
of second order in the displacements.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..model.clearances import ClearanceDisplacement
from ..errors import NoSolutionError
from ..model.manipulator import Manipulator, unit
from ..kinematics import FKSolution, as_poses, inverse_kinematics, solve_loop_closure


def displaced_pose(robot: Manipulator, poses: np.ndarray, displacement: ClearanceDisplacement | None = None,
                   variations: Mapping[str, Any] | None = None) -> np.ndarray:
    """Actual pose ``(..., 3)`` [mm, mm, rad] of the robot commanded to ``poses`` ``(..., 3)``.

    Parameters
    ----------
    displacement : clearance displacements (Eq. 16-18), fields ``(..., 3)`` or ``(3,)``
    variations : per-leg variations of link parameters (names of
        :data:`pmaccuracy.accuracy.error_model.LINK_VARIATIONS` except ``rho``), e.g. the
        assembly errors of Table 2; ``s`` is an actuation error.

    Raises
    ------
    NoSolutionError : the perturbed chain cannot be closed (errors far too large)
    """
    poses = as_poses(poses)
    s = inverse_kinematics(robot, poses).s
    var = {k: np.asarray(v, dtype=float) for k, v in (variations or {}).items()}
    unknown = set(var) - {"a", "alpha", "s", "beta", "d", "gamma", "theta", "r", "psi"}
    if unknown:
        raise ValueError(f"unknown variations {sorted(unknown)}")
    zero = np.zeros(3)
    dv = lambda name: var.get(name, zero)  # noqa: E731
    disp = displacement or ClearanceDisplacement.zeros()
    alpha = robot.alpha + dv("alpha")
    beta_p = alpha + robot.beta + dv("beta")
    gamma_p = beta_p + robot.gamma + dv("gamma") + disp.tau_g
    theta_p = gamma_p + robot.theta + dv("theta") + disp.tau_b
    c = ((robot.a + dv("a"))[..., None] * unit(alpha)
         + (s + dv("s"))[..., None] * unit(beta_p)
         + (robot.d + dv("d"))[..., None] * unit(gamma_p)
         + np.asarray(disp.sigma_g, float)[..., None] * unit(beta_p + np.pi / 2)   # guide play: normal to the rail
         + np.asarray(disp.rho, float)[..., None] * unit(disp.varphi))
    solution = solve_loop_closure(c, unit(theta_p), robot.r + dv("r"), robot.psi + dv("psi"))
    joints = np.stack([np.zeros_like(solution[2]), solution[2], np.zeros_like(solution[2])], axis=-1)
    fk = FKSolution(poses=solution[0], valid=solution[1], joints=joints, within_limits=solution[1])
    try:
        return fk.nearest(poses)
    except NoSolutionError:
        raise NoSolutionError("the perturbed loop cannot be closed: the errors are too large for this pose") \
            from None


def displaced_pose_error(robot: Manipulator, poses: np.ndarray, displacement: ClearanceDisplacement | None = None,
                         variations: Mapping[str, Any] | None = None) -> np.ndarray:
    """Exact pose error ``actual - commanded`` ``(..., 3)`` [mm, mm, rad] (phi difference wrapped to (-pi, pi])."""
    poses = as_poses(poses)
    err = displaced_pose(robot, poses, displacement, variations) - poses
    err[..., 2] = np.angle(np.exp(1j * err[..., 2]))
    return err


# ====================================================================== any architecture
def _perturbed_end(chain, q: np.ndarray, config, leg: int) -> tuple[np.ndarray, np.ndarray]:
    """End frame ``(angle, origin)`` of a leg chain with its joints at ``q (..., 3)`` and the source values
    of ``config`` (:class:`~pmaccuracy.model.sources.JointDisplacements`) inserted (module docstring of
    :mod:`pmaccuracy.model.sources`): before joint k a translation ``shift`` and a turn ``turn`` about its
    centre ``c_k``; a slide's block shifted by ``sigma`` normal to the rail and tilted by ``tau + tilt``
    about its centre: a bushing before the slide (at ``c_k``, the rod then slides along the tilted
    direction), a carriage after it (at ``c_k + q_k e_k``); ``dq`` on the actuated joint; the link ``dl``
    longer."""
    angle = np.full(q.shape[:-1], float(chain.base_angle))
    pos = np.full(q.shape[:-1], chain.base_z, dtype=complex)
    for k, joint in enumerate(chain.joints):
        pos = pos + config.shift[..., leg, k]
        angle = angle + config.turn[..., leg, k]
        value = q[..., k] + (config.dq[..., leg, k] if joint.actuated else 0.0)
        link = joint.link_z
        if abs(link) > 0:
            link = link * (1 + config.dl[..., leg, k] / abs(link))
        if joint.kind == "R":
            angle = angle + joint.offset + value
        else:
            angle = angle + joint.offset
            e = np.exp(1j * angle)
            pos = pos + config.sigma[..., leg, k] * 1j * e
            tilt = config.tau[..., leg, k] + config.tilt[..., leg, k]
            if joint.block_kind == "bushing":
                angle = angle + tilt
                pos = pos + value * np.exp(1j * angle)
            else:
                pos = pos + value * e
                angle = angle + tilt
        pos = pos + np.exp(1j * angle) * link
    return angle, pos


def _closure_residual(robot: Manipulator, z: np.ndarray, q_act: np.ndarray, config) -> np.ndarray:
    """Loop-closure residuals ``(..., 9)`` of unknowns ``z = [x, y, phi, passive joints (3 x 2)]``."""
    pz = z[..., 0] + 1j * z[..., 1]
    phi = z[..., 2]
    out = []
    for i, chain in enumerate(robot.chains):
        a = chain.actuated_index
        pi, pj = chain.passive_indices
        q = np.empty(z.shape[:-1] + (3,))
        q[..., a] = q_act[..., i]
        q[..., pi] = z[..., 3 + 2 * i]
        q[..., pj] = z[..., 4 + 2 * i]
        angle, pos = _perturbed_end(chain, q, config, i)
        target = pz + np.exp(1j * phi) * chain.platform_z
        d_angle = np.angle(np.exp(1j * (angle - phi - chain.platform_angle)))
        out += [pos.real - target.real, pos.imag - target.imag, d_angle * robot.characteristic_length]
    return np.stack(out, axis=-1)


def joint_displaced_pose(robot: Manipulator, poses: np.ndarray, config, iterations: int = 8) -> np.ndarray:
    """The exact pose ``(..., 3)`` [mm, mm, rad] of any architecture with the actuators held at the
    commanded poses' values and the error sources at ``config`` (a virtual prototype).

    Solves the three perturbed loop closures (:func:`_perturbed_end`) for the
    pose and the six passive joints by Newton's method from the commanded
    configuration (Jacobian by central differences, ``iterations`` steps);
    raises :class:`NoSolutionError` where the loops cannot be closed.
    """
    z, _ = closure_state(robot, poses, config, iterations=iterations, with_jacobian=False)
    out = z[..., :3].copy()
    out[..., 2] = np.angle(np.exp(1j * out[..., 2]))
    return out


def closure_state(robot: Manipulator, poses: np.ndarray, config, start: np.ndarray | None = None,
                  iterations: int = 8, with_jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """The closed perturbed loops of :func:`joint_displaced_pose` and their Jacobian there.

    Returns ``z`` ``(..., 9)``: the unknowns ``[x mm, y mm, phi rad, passive joints of legs 1-3 (rad or mm)]``
    (phi not wrapped) with the residual ``r(z) = 0`` of :func:`_closure_residual` (rows ``[x mm, y mm,
    angle * L mm]`` per leg, ``L`` the robot's characteristic length), and ``J = dr/dz`` ``(..., 9, 9)`` at ``z``
    (central differences; None without ``with_jacobian``). Newton's method starts at ``start`` ``(..., 9)`` (default: the commanded
    configuration of ``poses`` ``(..., 3)``, whose actuator values are held either way); raises
    :class:`NoSolutionError` where the loops cannot be closed.
    """
    poses = as_poses(poses)
    ik = inverse_kinematics(robot, poses)
    if not np.all(ik.reachable):
        raise NoSolutionError("a commanded pose cannot be reached by every leg")
    q_act = ik.q
    z = np.concatenate([poses, ik.passive.reshape(poses.shape[:-1] + (6,))], axis=-1) if start is None \
        else np.array(start, dtype=float)

    def jacobian(z: np.ndarray) -> np.ndarray:   # (..., 9, 9)
        h = 1e-7
        J = np.empty(z.shape[:-1] + (9, 9))
        for m in range(9):
            dz = np.zeros(9)
            dz[m] = h
            J[..., :, m] = (_closure_residual(robot, z + dz, q_act, config)
                            - _closure_residual(robot, z - dz, q_act, config)) / (2 * h)
        return J

    for _ in range(iterations):
        r = _closure_residual(robot, z, q_act, config)
        with np.errstate(invalid="ignore"):
            step = np.linalg.solve(jacobian(z), r[..., None])[..., 0]
        z = z - step
    r = _closure_residual(robot, z, q_act, config)
    closed = np.all(np.abs(r) < 1e-8, axis=-1)
    if not np.all(closed):
        raise NoSolutionError("the perturbed loops cannot be closed at " + _poses_text(poses, ~closed)
                              + ": the errors are too large there (or the pose is near a singularity)")
    return z, (jacobian(z) if with_jacobian else None)


def _poses_text(poses: np.ndarray, bad: np.ndarray, shown: int = 3) -> str:
    """``"pose (x, y, phi_deg)"`` of the first ``shown`` poses ``(..., 3)`` [mm, mm, rad] where ``bad``, and how
    many more: the poses an error message names.

    >>> _poses_text(np.array([[1.0, 2.0, 0.0], [3.0, 4.0, 0.5]]), np.array([False, True]))
    'pose (3, 4, 28.65 deg)'
    """
    pts = np.asarray(poses, dtype=float).reshape(-1, 3)[np.asarray(bad).reshape(-1)]
    text = ", ".join(f"({x:.4g}, {y:.4g}, {np.degrees(phi):.4g} deg)" for x, y, phi in pts[:shown])
    more = f" and {len(pts) - shown} more" if len(pts) > shown else ""
    return ("pose " if len(pts) == 1 else "poses ") + text + more

