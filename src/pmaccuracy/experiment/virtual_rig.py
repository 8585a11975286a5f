"""The virtual rig: the push protocol of Sec. 5.2 played on a simulated prototype.

:func:`simulate_readings` drives the clearances (or the per-joint error
sources of any architecture) to the worst-case configuration of each push
direction and reads the pose the perturbed loops close at (or its first-order
estimate), plus camera noise; :func:`simulate_experiment` does so on a grid of
the constant-orientation workspace (:func:`grid_poses`). The result is a
:class:`~pmaccuracy.experiment.measurements.Measurements`, written with
:func:`~pmaccuracy.experiment.measurements.write_measurements`.

Units: mm and rad in the arrays; noise of orientation readings in degrees (``noise_deg``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..accuracy.bounds import PoseErrorBounds, first_order_pose_error, max_pose_errors
from ..model.clearances import ClearanceDisplacement, ClearanceSet
from ..accuracy.error_model import pose_state
from ..errors import ConfigError
from ..model.manipulator import Manipulator
from ..model.plausibility import check_orientations
from ..kinematics import as_poses, regular_mask
from .measurements import DEFAULT_ACCURACY_DEG, DEFAULT_ACCURACY_MM, Measurements
from ..model.sources import ErrorSources
from ..io.resolve import load_clearances
from ..io.resolve import robot_arg
from ..accuracy.nonlinear import displaced_pose
from ..accuracy.nonlinear import joint_displaced_pose
from ..kinematics import inverse_kinematics
from ..kinematics.workspace import constant_orientation_workspace
from ..model.sources import first_order_error, worst_configuration
from ..accuracy.loads import DEFAULT_THRESHOLD_N, Load, loaded_pose_error, wrench_rows
from ..kinematics import DEFAULT_MAX_CONDITION

#: Reading models of the virtual experiment.
MODELS = ("exact", "first_order")


def opposite(displacement: ClearanceDisplacement) -> ClearanceDisplacement:
    """The mirror configuration: tilts and shifts negated, revolute offset turned by pi.

    The clearance sets (Eq. 16-18) are symmetric, so it is feasible, and its
    first-order pose error (Eq. 19) is exactly the negative of the original's.
    """
    return ClearanceDisplacement(tau_b=-displacement.tau_b, sigma_g=-displacement.sigma_g,
                                 tau_g=-displacement.tau_g, rho=displacement.rho, varphi=displacement.varphi + np.pi)


def push_configurations(bounds: PoseErrorBounds, take_up: float = 1.0) -> tuple[ClearanceDisplacement, ...]:
    """Clearance displacements of the six pushes :data:`PUSHES`, fields ``(n, 3)``.

    A push along ``+x`` drives every clearance to the configuration moving the
    platform furthest in +x, i.e. the argmax of Eq. 21 for x
    (``bounds.worst["dx"]``, from ``max_pose_errors(..., details=True)``); ``-x``
    to its mirror (:func:`opposite`); likewise ``+-y`` with ``worst["dy"]`` and
    ``+-r`` with ``worst["dphi"]``. ``take_up`` in [0, 1] scales every
    displacement (a push that only partly takes up the clearances).
    """
    if not bounds.worst:
        raise ValueError("push_configurations needs max_pose_errors(..., details=True)")
    out = []
    for q in ("dx", "dy", "dphi"):
        worst = bounds.worst[q].scaled(take_up)
        out += [worst, opposite(worst)]
    return tuple(out)


def push_loads(robot: Manipulator, push_n: float) -> tuple[Load, ...]:
    """The loads of the six pushes :data:`PUSHES` with a push force of ``push_n`` N: ``+-x``, ``+-y`` a force of
    ``push_n`` N, ``+-r`` a moment of ``push_n`` times the robot's characteristic length (N mm)."""
    if not (math.isfinite(push_n) and push_n > 0):
        raise ConfigError(f"must be a force > 0 (N), got {push_n:g}", key="push_n")
    L = robot.characteristic_length
    return (Load(fx=push_n), Load(fx=-push_n), Load(fy=push_n), Load(fy=-push_n), Load(m=push_n * L),
            Load(m=-push_n * L))


def predict_pushes(robot: Manipulator | str, clearances, poses: np.ndarray, push_n: float, *,
                   threshold: float = DEFAULT_THRESHOLD_N, allow_outside: bool = False,
                   max_condition: float = DEFAULT_MAX_CONDITION) -> tuple[np.ndarray, np.ndarray]:
    """What each push of force ``push_n`` N does to the platform (first order, loaded model):
    ``(displacement, spread)``, each ``(n, 6, 3)`` [mm, mm, rad] for the pushes :data:`PUSHES`.

    With the error zonotope's generators ``g_i = c_i A^-1[:, i]`` (``max_pose_errors(details=True)``) and each
    push's leg intensities ``lambda = -A^-T W`` (:mod:`pmaccuracy.accuracy.loads`), the displacement is
    ``sum_i g_i t_i`` with ``t_i = -sign(lambda_i)`` (the loaded pose error of
    :func:`pmaccuracy.accuracy.loads.loaded_pose_error`; ``t_i = 0`` for a leg with ``|lambda_i| <= threshold``)
    and the spread ``sum over unloaded i of |g_i|``, the half-width of the range such legs leave.
    ``allow_outside`` evaluates nominal poses outside the joint ranges too (``experiment compare`` accepts
    nominal poses a few micrometres outside); singular poses are refused.

    >>> d, s = predict_pushes("aalborg_3ppr", "case1", [[0.0, 0.0, 0.0]], 10.0)
    >>> b = max_pose_errors("aalborg_3ppr", "case1", [[0.0, 0.0, 0.0]])
    >>> bool(np.isclose(d[0, 0, 0], b.dx_max[0]) and np.isclose(d[0, 1, 0], -b.dx_max[0]))   # +x and -x pushes
    True
    """
    robot = robot_arg(robot)
    clearances = load_clearances(clearances, robot)
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {threshold}", key="threshold")
    sources = clearances if isinstance(clearances, ErrorSources) else ErrorSources.from_clearance_set(clearances)
    poses = as_poses(poses).reshape(-1, 3)
    loads = push_loads(robot, push_n)
    b = max_pose_errors(robot, sources, poses, details=True, allow_outside=allow_outside,
                        max_condition=max_condition)
    A = wrench_rows(robot, poses)                                               # (n, 3, 3)
    W = np.stack([load.wrench(poses) for load in loads], axis=1)                # (n, 6, 3)
    lam = -np.linalg.solve(np.swapaxes(A, -1, -2)[:, None], W[..., None])[..., 0]
    unloaded = np.abs(lam) <= threshold
    t = np.where(unloaded, 0.0, -np.sign(lam))
    G = b.generators                                                            # (n, 3, 3): columns g_i
    return np.einsum("nqi,npi->npq", G, t), np.einsum("nqi,npi->npq", np.abs(G), unloaded.astype(float))


def _check_simulation(take_up: float, noise_mm: float, noise_deg: float, model: str) -> None:
    if not (math.isfinite(take_up) and 0.0 <= take_up <= 1.0):
        raise ConfigError(f"must be a fraction in [0, 1] (share of the clearance a push takes up), got {take_up:g}",
                          key="take_up")
    for name, value in (("noise_mm", noise_mm), ("noise_deg", noise_deg)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ConfigError(f"must be a finite standard deviation >= 0, got {value:g}", key=name)
    if model not in MODELS:
        raise ConfigError(f"unknown reading model {model!r} (choose from {', '.join(MODELS)})", key="model")


def simulate_readings(robot: Manipulator | str, clearances: ClearanceSet | str, poses: np.ndarray, *,
                      take_up: float = 1.0, noise_mm: float = DEFAULT_ACCURACY_MM,
                      noise_deg: float = DEFAULT_ACCURACY_DEG, model: str = "exact",
                      seed: int | np.random.Generator | None = None, labels: Sequence[str] | None = None,
                      source: str = "virtual experiment", push_n: float | None = None) -> Measurements:
    """Play the push protocol of Sec. 5.2 on a simulated rig at nominal poses ``(n, 3)`` [mm, mm, rad].

    For each pose and push (:func:`push_configurations`) the clearances sit in
    the worst-case configuration of that push direction, scaled by ``take_up``;
    the reading is then

    * ``model="exact"`` (default): the pose closing the perturbed loops exactly
      with the actuators locked (:func:`pmaccuracy.accuracy.nonlinear.displaced_pose`).
      This is the default because it plays the role of the physical prototype:
      the rig should not share the linearization of the model it validates;
    * ``model="first_order"``: nominal pose + ``J^c_err delta^c`` (Eq. 19,
      :func:`pmaccuracy.accuracy.bounds.first_order_pose_error`),

    plus independent Gaussian camera noise on every reading, standard deviations
    ``noise_mm`` on x and y and ``noise_deg`` on phi (Sec. 5: 0.01 mm, 0.01 deg),
    drawn from ``numpy.random.default_rng(seed)``.

    What to expect (derived; checked in ``tests/experiment/test_experiment.py``).
    With ``take_up = 1`` and no noise, the first-order readings of ``+x`` and
    ``-x`` are ``x_nom +- dx_max`` and every other reading lies in between (all
    are points of the symmetric error set), so the range of Eq. 23a is exactly
    ``2 dx_max``; likewise dy and dphi; ``dp = 2 max_t |e_xy(worst_t)| <= 2 dp_max``.
    The exact readings differ by second-order terms; the even ones shift ``+t``
    and ``-t`` alike and cancel in a range, so the relative difference is far
    below the clearance size (~1e-5 for the presets). With noise ``sigma``, when
    each extreme is attained by a single reading with a margin of several
    ``sigma`` over the others, ``range - 2 d_max = eps_a - eps_b ~ N(0, 2 sigma^2)``:
    the RMSD of (measured - 2 predicted) tends to ``sqrt(2) sigma``. If ``k``
    readings tie at an extreme (the Aalborg robot's ``+x`` push also attains
    ``+dphi_max``, so dphi has ``k = 2`` at both ends), that end is the maximum of
    ``k`` noises, of mean ``sigma / sqrt(pi)`` for ``k = 2`` and mean square
    ``sigma^2``, and the RMSD becomes ``sigma sqrt(2 (1 + 1/pi))`` for ``k = 2``
    at both ends.

    With ``push_n`` (N) each push is a load instead (:func:`push_loads`): every clearance is taken up along its
    joint's reaction (:func:`pmaccuracy.accuracy.loads.loaded_pose_error`), so each reading is the predicted
    loaded pose, not only an extreme of the error set. A leg the push leaves unloaded keeps its clearances
    centred (its state is undetermined: :func:`predict_pushes` gives the range). For pushes along the axes
    of a robot whose legs are all loaded this is the same configuration as the worst case of that direction.

    Parameters
    ----------
    labels : point labels (default ``"1"``, ``"2"``, ...)

    Raises
    ------
    ConfigError : take_up outside [0, 1], negative noise, unknown model
    OutsideJointLimitsError, SingularPoseError : unusable nominal poses
    """
    check_orientations(poses, "poses", poses=True)
    robot = robot_arg(robot)
    clearances = load_clearances(clearances, robot)
    _check_simulation(float(take_up), float(noise_mm), float(noise_deg), model)
    poses = as_poses(poses).reshape(-1, 3)
    if push_n is not None:
        sources = clearances if isinstance(clearances, ErrorSources) else ErrorSources.from_clearance_set(clearances)
        readings = _loaded_pushes(robot, sources, poses, float(push_n), float(take_up), model)
    elif isinstance(clearances, ErrorSources):  # any architecture: per-joint sources
        readings = _generic_pushes(robot, clearances, poses, float(take_up), model)
    else:
        bounds = max_pose_errors(robot, clearances, poses, details=True)
        pushes = push_configurations(bounds, float(take_up))
        if model == "first_order":
            state = pose_state(robot, poses)
            readings = np.stack([poses + first_order_pose_error(robot, state, d) for d in pushes], axis=1)
        else:
            readings = np.stack([displaced_pose(robot, poses, d) for d in pushes], axis=1)
    if model != "first_order":
        # Keep phi next to the nominal value (displaced_pose wraps to (-pi, pi]).
        readings[..., 2] = poses[:, None, 2] + np.angle(np.exp(1j * (readings[..., 2] - poses[:, None, 2])))
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    sigma = np.array([noise_mm, noise_mm, math.radians(noise_deg)])
    readings = readings + rng.standard_normal(readings.shape) * sigma
    if labels is None:
        labels = [str(k + 1) for k in range(poses.shape[0])]
    return Measurements(points=np.asarray(labels, dtype=str), nominal=poses, readings=readings, source=source)


def _loaded_pushes(robot: Manipulator, sources: ErrorSources, poses: np.ndarray, push_n: float, take_up: float,
                   model: str) -> np.ndarray:
    """Readings ``(n, 6, 3)`` of the six pushes as loads of ``push_n`` N (:func:`push_loads`)."""
    readings = []
    for load in push_loads(robot, push_n):
        res = loaded_pose_error(robot, sources, poses, load, exact=False)
        cfg = res.configuration.scaled(take_up)
        readings.append(poses + res.first_order * take_up if model == "first_order"
                        else joint_displaced_pose(robot, poses, cfg))
    return np.stack(readings, axis=1)


def _generic_pushes(robot: Manipulator, sources: ErrorSources, poses: np.ndarray, take_up: float,
                    model: str) -> np.ndarray:
    """Readings ``(n, 6, 3)`` of the six pushes with per-joint sources (any architecture).

    A push along ``+x`` puts every source at the extreme that moves the platform
    furthest in +x (:func:`pmaccuracy.model.sources.worst_configuration` with the signs
    of ``max_pose_errors(...).worst_signs["dx"]``), ``-x`` at the opposite one
    (the sets are symmetric), likewise y and the rotation; scaled by ``take_up``.
    """

    bounds = max_pose_errors(robot, sources, poses, details=True)
    joints = inverse_kinematics(robot, poses).joints
    readings = []
    for q in ("dx", "dy", "dphi"):
        cfg = worst_configuration(robot, sources, joints, poses, bounds.worst_signs[q]).scaled(take_up)
        for c in (cfg, -cfg):
            if model == "first_order":
                readings.append(poses + first_order_error(robot, joints, poses, c))
            else:
                readings.append(joint_displaced_pose(robot, poses, c))
    return np.stack(readings, axis=1)


def grid_poses(robot: Manipulator, phi: float, grid: int) -> np.ndarray:
    """Nominal poses ``(m, 3)`` [mm, mm, rad] of the virtual experiment (the paper's i x j points).

    The points of a ``grid x grid`` lattice over the bounding box of the
    constant-orientation workspace at ``phi`` that lie inside it
    (:meth:`pmaccuracy.kinematics.workspace.Workspace.grid`) and are not near a singularity
    (:func:`pmaccuracy.kinematics.regular_mask`), ordered by y, then x;
    coordinates rounded to 1e-10 mm.
    """

    if int(grid) != grid or grid < 2:
        raise ConfigError(f"the grid needs at least 2 points per axis, got {grid}", key="grid")
    x, y, inside = constant_orientation_workspace(robot, float(phi)).require_nonempty().grid(int(grid))
    X, Y = np.meshgrid(np.round(x, 10), np.round(y, 10))  # tidy -2e-14 into 0; 5e-11 mm is far below the limit slack
    poses = np.column_stack([X[inside], Y[inside], np.full(int(inside.sum()), float(phi))])
    # points on a singular curve inside the workspace (other architectures than the 3-PPR) cannot be measured
    return poses[regular_mask(robot, poses)]


def simulate_experiment(robot: Manipulator | str, clearances: ClearanceSet | str, phi: float, grid: int = 5, *,
                        take_up: float = 1.0, noise_mm: float = DEFAULT_ACCURACY_MM,
                        noise_deg: float = DEFAULT_ACCURACY_DEG, model: str = "exact",
                        seed: int | np.random.Generator | None = None, push_n: float | None = None) -> Measurements:
    """Virtual experiment at orientation ``phi`` (rad) on the grid points of :func:`grid_poses`.

    See :func:`simulate_readings` for the readings; write them with :func:`write_measurements`.
    """
    check_orientations(phi, "phi")
    robot = robot_arg(robot)
    clearances = load_clearances(clearances, robot)
    _check_simulation(float(take_up), float(noise_mm), float(noise_deg), model)
    poses = grid_poses(robot, phi, grid)
    return simulate_readings(robot, clearances, poses, take_up=take_up, noise_mm=noise_mm, noise_deg=noise_deg,
                             model=model, seed=seed,
                             source=f"virtual experiment ({robot.name}, {clearances.name}, phi = "
                                    f"{math.degrees(phi):g} deg, {model}, take-up {take_up:g})", push_n=push_n)

