"""Virtual prototype: the exact (nonlinear) loop closure with errors and clearance displacements.

The first-order model of :mod:`pmaccuracy.error_model` and :mod:`pmaccuracy.bounds`
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

from .clearances import ClearanceDisplacement
from .errors import NoSolutionError
from .geometry import Manipulator, unit
from .kinematics import FKSolution, as_poses, inverse_kinematics, solve_loop_closure


def displaced_pose(robot: Manipulator, poses: np.ndarray, displacement: ClearanceDisplacement | None = None,
                   variations: Mapping[str, Any] | None = None) -> np.ndarray:
    """Actual pose ``(..., 3)`` [mm, mm, rad] of the robot commanded to ``poses`` ``(..., 3)``.

    Parameters
    ----------
    displacement : clearance displacements (Eq. 16-18), fields ``(..., 3)`` or ``(3,)``
    variations : per-leg variations of link parameters (names of
        :data:`pmaccuracy.error_model.LINK_VARIATIONS` except ``rho``), e.g. the
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
