"""Certified worst-case pose errors of the exact (nonlinear) loop closure, and the best feasible nonlinear maxima.

The first-order maxima of :mod:`pmaccuracy.accuracy.bounds` are exact for the linearized model ``A dX = e`` but
the true, nonlinear worst case is slightly larger (0.04-0.27 % at the paper's clearances). Here every
quantity gets two numbers:

* an **upper bound** that is guaranteed never below the maximum of the exact loop closure over the whole
  error set (first-order maximum plus a rigorous bound of the Taylor remainder, below), and
* a **lower bound**, the best feasible configuration of the exact model (:func:`nonlinear_pose_errors`:
  local ascent from the first-order worst vertices), with the relative ``gap = (upper - lower) / lower``.

Error set
---------
The sources of :mod:`pmaccuracy.model.sources` with non-zero half-width are the parameters ``delta`` (``n``
scalars, mm or rad). Each source ranges over its own set and the sets are independent (their product
``S``): an *interval* ``|delta| <= eps`` (``direction``: a turn about the joint's centre; ``angular``: a tilt of
a slide's block about its centre; ``actuator``, ``length``),
a *disk* ``|(dx, dy)| <= eps`` (``radial`` + ``position`` as one shift, global axes) or a *rhombus*
``|L tau +- 2 sigma| <= 2 eps`` (``lateral``). The support function of a linear form ``c . delta`` over
``S`` is the sum of the sources' own: ``eps |c|`` (interval), ``eps ||c||_2`` (disk),
``max(eps |c_sigma|, 2 eps |c_tau| / L)`` (rhombus).

Exact closure as a sum of rotated terms
---------------------------------------
Let ``v = (z, delta)`` with ``z`` the nine unknowns (pose ``x, y, phi`` and the six passive joints) and
write ``Delta = v - v0`` for the change from the commanded configuration ``v0 = (z0, 0)``. Walking each leg's
chain (:func:`pmaccuracy.accuracy.nonlinear._perturbed_end`: shift and turn before joint ``k``, joint motion, a
slide's block shifted and tilted about its centre (a bushing before the slide, a carriage after it), link)
every frame angle is *affine* in ``v`` and every translation is a term ``r_m(v) exp(i theta_m(v))`` with
``r_m`` (complex) and ``theta_m`` affine, plus affine shifts; terms whose angles differ by a constant are
merged into one (:func:`~pmaccuracy.accuracy.certified.closure._merge_terms`). So the three closures are,
for leg ``i``::

    F_i(v) = sum_m r_m exp(i theta_m) + (affine)  - p - exp(i phi) platform_i = 0      (complex, mm)
    G_i(v) = (affine frame angle) - phi - platform_angle_i = 0                          (rad, exact affine)

With ``Dr = r_m - r_m0`` and ``Dt = theta_m - theta_m0`` (both linear in ``Delta``) the remainder of one
term after its linearization is, exactly::

    R_m = exp(i theta_m0) [ r_m0 (exp(i Dt) - 1 - i Dt) + Dr (exp(i Dt) - 1) ]                    (1)

and the elementary inequalities ``|exp(ix) - 1| <= |x|``, ``exp(ix) - 1 - ix = -x^2/2 + rho3`` with
``|rho3| <= |x|^3 / 6`` bound it.

Remainder of the pose
---------------------
Let ``J = [J_z, J_delta]`` be the Jacobian of the nine real residuals ``(Re F_i, Im F_i, G_i)`` at ``v0``
and ``F0`` the (rounding-size) residual there. The first-order solution is ``Dz_lin = M delta`` with
``M = -J_z^-1 J_delta`` (its pose rows are the first-order error map of :mod:`pmaccuracy.accuracy.bounds`), and
the exact solution is ``Dz = M delta + w`` with::

    w = -J_z^-1 (F0 + R(M delta + w, delta))                                                      (2)

For a componentwise bound ``|w| <= b`` every ``Dt_m = alpha_m . delta + a_m . w`` is at most
``X_m = h_S(alpha_m) + |a_m| . b`` (``h_S``: support function, ``alpha_m = a_m,z M + a_m,delta``) and
every ``|Dr_m| <= D_m = hypot(h_S(Re beta_m), h_S(Im beta_m)) + |r'_m,z| . b``. By (1)
``|R_i| <= rho_i(b) = sum_m |r_m0| X_m^2 / 2 + D_m X_m`` and with ``kappa_ji = J_z^-1[j, Re_i] + i
J_z^-1[j, Im_i]``::

    |w_j| <= Phi_j(b) = |(J_z^-1 F0)_j| + sum_i |kappa_ji| rho_i(b)                               (3)

Iterating ``b <- Phi(b)`` from ``b = 0`` (monotone) gives ``b`` with ``Phi(b) <= b`` after a small outward
inflation; the map (2) then sends the box ``|w| <= b`` into itself (Brouwer: a solution exists in it). Its
Lipschitz constant in ``w`` over the box, from ``d R_m / d w = r'_z (e^{i theta} - e^{i theta0}) + i
theta'_z (r e^{i theta} - r0 e^{i theta0})`` bounded by ``|r'_z| X_m + |theta'_z| (D_m + |r_m0| X_m)``,
must be below 1 (checked in the norm ``max_j |w_j| / b_j``): then the solution in the box is unique,
``J_z`` is invertible on it, and by the implicit function theorem it is the continuation of the
commanded assembly over the connected set ``S`` -- the configuration Newton's method from the
commanded pose finds (:func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`). When either check fails
(errors too large, near a singularity, a configuration that cannot be assembled) no bound is returned:
:class:`~pmaccuracy.errors.CertificationError` or NaN.

Term-by-term bound. For a pose row ``j`` and direction ``s = +-1``, with ``c_m = conj(kappa_ji) exp(i
theta_m0) r_m0`` (``i`` the leg of term ``m``)::

    s Dz_j <= h_S(s M_j) + s w_j,
    s w_j <= -s (J_z^-1 F0)_j + sum_m [ max(s Re c_m, 0) X_m^2/2 + |c_m| X_m^3/6 + |kappa_ji| D_m X_m ]   (4)

(the ``Dt^2`` terms keep their sign). This is valid but loose: the bilinear ``Dr Dt`` terms lose their
sign and every term takes its own maximum over ``S``.

Second-order model (the tight bound). With ``c'_m = conj(kappa_ji) exp(i theta_m0)``, expanding (1) by
``exp(ix) - 1 - ix = -x^2/2 + rho3`` and ``exp(ix) - 1 = ix + rho2`` (``|rho2| <= x^2/2``) and splitting
``Dt = alpha_m . delta + a_m,z . w``, ``Dr = beta_m . delta + r'_m,z . w``::

    s w_j = -s (J_z^-1 F0)_j + delta^T H delta + E,
    H = s sum_m [ Re(c_m) alpha_m alpha_m^T / 2 + sym(Im(c'_m beta_m) alpha_m^T) ]                      (5)
    |E| <= sum_m |c_m| (om_t (2 hX_m + om_t) / 2 + X_m^3 / 6) + |c'_m| (om_r X_m + hD_m om_t + D_m X_m^2 / 2)

with ``om_t = |a_m,z| . b >= |Dt - alpha_m . delta|``, ``om_r = |r'_m,z| . b``, ``hX_m = h_S(alpha_m)``,
``hD_m`` the bound of ``|beta_m . delta|``. So ``s Dz_j <= max_S (s M_j . delta + delta^T H delta) - s
(J_z^-1 F0)_j + E``, and the maximum of the quadratic over ``S`` is bounded by Lagrangian duality
(:func:`dual_bound`: ``S`` as quadratic constraints ``delta^T P_k delta <= 1``; for any ``lambda >= 0``
with ``sum lambda_k P_k - H`` positive definite, ``max <= sum lambda_k + g^T (sum lambda_k P_k - H)^-1 g /
4``), which equals the first-order support function at ``H = 0`` and exceeds the true maximum of the
model only by ``O(|H|^2 / |g|)``. The certified value is the smaller of this and (4).

The box ``b`` is first tightened the same way: ``|w_j| <= max_s [dual bound of max_S delta^T (s H_j) delta
- s (J_z^-1 F0)_j] + E_j(b)`` is another bound of the map (2) over the box, monotone in ``b``, so
``b <- min(b, Phi(b), that)`` keeps ``Phi(b) <= b`` (repeated until it stops shrinking).

``dx, dy, dphi`` take the larger of ``s = +-1``. For ``|dp|`` the same bounds are applied to ``u . (Dx,
Dy)`` for ``K = 256`` unit directions ``u_k`` (the cheap start value of :func:`dual_bound` for all, the
refined one for those whose bound exceeds the best refined one) and ``|p| <= max_k u_k . p / cos(pi /
K)``. Rounding: :func:`_dual_value` bounds the smallest eigenvalue from below and corrects the quadratic
form by its residual; every result is finally multiplied by ``1 + 1e-9`` and increased by ``1e-12 *
scale``.

Cutting the set. Where the bound is not certified or exceeds the best feasible value by more than
0.5 %, :func:`certified_pose_errors` bounds again over ``2^split`` pieces (:func:`_split_bounds`: the
interval sources that turn the chains most are halved; each piece is expanded about the exact closure at its
centre, so its remainder terms shrink) and keeps the smaller valid bound. A bound still missing, or more
than ``split_gap`` above the best feasible value, goes to branch and bound (:func:`_branch_and_bound`):
every piece not yet used or above the target is cut along its source of largest turning weight (intervals
halved and lateral rhombi quartered, both exact partitions; a disk covered by :data:`DISK_SECTORS` sectors,
each certified as the rectangle that contains it, :func:`sector_rect`, and a sector halved in angle or
radius), each child bounded about its own exact centre, until all are within the target or ``max_pieces``
pieces have been bounded. The bound is the largest over the leaves, which cover ``S``, of each leaf's own
bound capped by those of its used ancestors (an ancestor's bound holds over the leaf's part of ``S``; the
sector rectangles stick out of their disk, so a first cut can be looser than its parent). A pose whose
whole set could not be certified is certified this way when every leaf is used (budget ``REFUSED_BUDGET``
times larger once some piece is used). The extreme points of every used piece are solved exactly too and
raise the best feasible values (and so the targets) as it goes.

Continuation check. A piece's certificate proves one solution in a box about the Newton solution at its
centre, unique there, but Newton's method could have converged to another solution branch. A piece is
therefore used only if its solution is shown to be the commanded assembly's continuation; otherwise it
counts as not certified (it may be cut again; a set with an unused piece keeps its uncut bound, or is
refused if it has none; ``rejected`` counts such pieces). The argument: some point ``d`` of the piece has
a proven box of the continuation (an *anchor*) that lies inside the piece's box ``|Dz - dz - M (d - c)| <=
b`` at ``d``; by the piece's uniqueness its solution at ``d`` is then the continuation. The first anchor is
the commanded assembly, ``|Dz| <= b0`` at ``d = 0`` (:func:`_point_box`, rounding-size); the four pieces of
the first cut and the root of the branch and bound contain ``d = 0``. Every used piece adds anchors: its
centre (``|Dz - dz| <= bc``, ``bc``: equation (3) iterated at ``delta = c``, where the ``h_S`` terms
vanish) and the centre ``c_P`` of every cut piece it contains (every child of ``P`` contains ``c_P``):
Newton's method at ``c_P`` and a point certificate there (:func:`_point_anchor`) whose box lies in the used
piece's box. (In :func:`_split_bounds` a piece may also be checked *inside the parent*: its centre box in
the whole set's certified box, :func:`_continues`.) The piece's solution and the continuation are
continuous solution branches on the connected piece with ``J_z`` invertible (contraction), equal at one
point, so equal on the whole piece (implicit function theorem: the set where they agree is open and
closed). Measured: no piece rejected on the paper robot or the random robots of the tests at 1x and 10x; a
Newton solution moved to another branch (test) is rejected.

Batched pipeline (:func:`certified_pose_errors`). All poses at once: feasible values first (12 exact closures a
pose at the first-order worst vertices, their negatives and the refined ``|dp|`` directions: the chord method with
one inverse of ``J_z`` a pose); then the box of
(3) alone (the second bound of the box only where it does not close or contract), the bound (4) of every row
and the dual bound (5) (batched, one row per pose and direction) only for the rows whose bound (4) is above
``1 + REFINE_FRACTION * split_gap`` times the best feasible value, refined only while above it; the local
ascent (gradient steps between vertices) only at the poses whose bound is still above that, whose targets it
raises; the poses still above ``split_gap`` get the tightened box with refined multipliers and every row
refined (one batch, unless ``refine=False``); only the poses still above it go on to the split and the branch and bound. Every value kept is one of the valid bounds
above, so the guarantee is the same; the gap at the paper's clearances is up to 0.1 % (``REFINE_FRACTION``).

Guarantee: for every configuration in ``S`` the exact pose error (continued from the commanded assembly)
satisfies ``|dx| <= dx_upper`` etc. Joint ranges are not imposed on the perturbed passive joints.
Tightness (guide: docs/guide/methods.md; tests): within 0.01 % of the best configuration at the paper's clearances and 0.33 % at
10x on the Aalborg 3-PPR; on 25 random robots within 0.5 % of the dense search at 1x (24 certified, one
65 % nonlinear among them) and within 3.9 % at 10x (19 certified, up to 44 % nonlinear). Refused: robots
that cannot be closed over their whole error set, and a 3-RRR 75 % nonlinear at 10x (within the default
budget). Speed (batches of 200 poses, shared 2-core machine, ``benchmarks/bench_certified.py``): 0.4-1.3 ms a pose at
the presets' clearances, at 10x 0.6-1.0 ms with ``split_gap=0.05`` and 6-40 ms with the default 0.005 (the tight
dual bound and the cut set for more poses); a pose cut up to the budget takes seconds, up to tens of seconds with
no whole-set certificate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..._display import html_table, summary, value_range

from ...errors import CertificationError
from ...model.plausibility import check_orientations, warn
from .ascent import _ascent, _first_order_starts, _nonlinear, _objective_gradient  # noqa: F401 (the package's names)
from .branch import (  # noqa: F401 (the package's names)
    DISK_SECTORS,
    PIECE_DIRECTIONS,
    REFUSED_BUDGET,
    _branch_and_bound,
    _children,
    _contains,
    _piece_bounds,
    _point_anchor,
    _split_bounds,
)
from .closure import (  # noqa: F401 (the package's names)
    _Aff,
    _build_model,
    _merge_terms,
    _Model,
    _objective,
    _take,
    _take_many,
    exact_change,
)
from .dual import _dual_bound_flat, _dual_value, _sdp_dual, dual_bound  # noqa: F401 (the package's names)
from .error_set import MU_EVERY, MU_FACTOR, ROUND_ABS, ROUND_REL  # noqa: F401
from .error_set import (  # noqa: F401 (the package's names)
    CONTRACTION,
    HARD_CASE_GRADIENT,
    N_DIRECTIONS,
    PIECE_RTOL,
    QUANTITIES,
    SourceSet,
    _rect_coords,
    argsupport,
    constraint_matrices,
    error_set,
    project,
    sector_rect,
    support,
    to_displacements,
)
from .remainder import (  # noqa: F401 (the package's names)
    _certify,
    _contains_zero,
    _continues,
    _first_order_dp,
    _point_box,
    _prepare,
    _recentre,
    remainder_bounds,
)
from ..bounds import max_pose_errors

#: :func:`certified_pose_errors` refines the dual bound (5) of a row only while it exceeds the best feasible value by
#: more than this fraction of ``split_gap`` (the cheaper bound of every other row is kept: valid, and tight enough).
REFINE_FRACTION = 0.2
#: A certified bound more than this above the best feasible value is returned with a PlausibilityWarning.
GAP_WARNING = 0.05


# ============================================================================ certificate
@dataclass(frozen=True)
class CertifiedPoseErrors:
    """Certified and attained worst-case pose errors at a batch of ``N`` poses (module docstring); mm, rad for
    dphi.

    Attributes
    ----------
    poses : ``(N, 3)`` [mm, mm, rad]
    upper : ``{q: (N,)}`` certified upper bounds of the exact maxima (``q`` in :data:`QUANTITIES`; NaN where
        no certificate, see ``reason``)
    lower : ``{q: (N,)}`` best feasible values of the exact model (nonlinear maxima; NaN when not searched)
    first_order : ``{q: (N,)}`` the first-order maxima (:func:`pmaccuracy.accuracy.bounds.max_pose_errors`)
    gap : ``{q: (N,)}`` ``(upper - lower) / lower`` (0 where both are 0)
    worst : ``{q: (N, n)}`` the source values attaining ``lower`` (``delta``, module docstring)
    remainder : ``(N, 9)`` the bound ``b`` of ``|w|`` (pose rows mm, mm, rad; then passive joints)
    reason : ``(N,)`` empty where certified, else why not
    sets : the error set's sources (their ``cols`` index ``worst``)
    rejected : ``(N,)`` pieces of the cut error set certified but not used because the continuation check
        failed (module docstring, "Continuation check")
    """

    poses: np.ndarray
    upper: dict[str, np.ndarray]
    lower: dict[str, np.ndarray]
    first_order: dict[str, np.ndarray]
    gap: dict[str, np.ndarray]
    worst: dict[str, np.ndarray] = field(default_factory=dict)
    remainder: np.ndarray | None = None
    reason: np.ndarray | None = None
    sets: tuple[SourceSet, ...] = ()
    rejected: np.ndarray | None = None

    def __repr__(self) -> str:
        parts = [f"{q} upper {value_range(self.upper[q], 'deg' if q == 'dphi' else 'mm', 180 / math.pi if q == 'dphi' else 1.0)}"
                 for q in QUANTITIES]
        gaps = np.concatenate([np.ravel(self.gap[q]) for q in QUANTITIES])
        if np.any(np.isfinite(gaps)):
            parts.append(f"largest gap {np.nanmax(gaps) * 100:.3g} %")
        refused = int(np.sum(np.asarray([bool(r) for r in np.ravel(self.reason)])))
        if refused:
            parts.append(f"{refused} not certified")
        return summary("CertifiedPoseErrors", int(self.poses.shape[0]), parts)

    def _repr_html_(self) -> str:
        return html_table("Certified upper bounds (mm, deg)", self.records())

    def records(self, which: str = "upper") -> list[dict]:
        """One dict per pose with the ``bounds`` keys (x, y, phi_deg, dx_max, dy_max, dphi_max_deg, dp_max: the
        ``upper`` or ``lower`` values, mm and deg) and ``gap`` ``{dx, dy, dphi, dp}``."""
        vals = self.upper if which == "upper" else self.lower
        out = []
        for k, p in enumerate(self.poses):
            out.append({"x": float(p[0]), "y": float(p[1]), "phi_deg": float(np.degrees(p[2])),
                        "dx_max": float(vals["dx"][k]), "dy_max": float(vals["dy"][k]),
                        "dphi_max_deg": float(np.degrees(vals["dphi"][k])), "dp_max": float(vals["dp"][k]),
                        "gap": {q: float(self.gap[q][k]) for q in QUANTITIES}})
        return out


def certified_pose_errors(robot, clearances, poses, *, search: bool = True, allow_outside: bool = False,
                          on_failure: str = "raise", split: int = 2, split_gap: float = 0.005,
                          max_pieces: int = 256, ascent: bool = False, refine: bool = True) -> CertifiedPoseErrors:
    """Certified upper bounds of the exact worst-case ``|dx|, |dy|, |dphi|, |dp|`` and the best feasible values.

    Parameters
    ----------
    robot : :class:`~pmaccuracy.model.manipulator.Manipulator`, preset name or TOML path (any architecture)
    clearances : per-joint :class:`~pmaccuracy.model.sources.ErrorSources`, a 3-PPR
        :class:`~pmaccuracy.model.clearances.ClearanceSet` (bearing = ``angular`` on joint 2, guide play =
        ``lateral`` on joint 1, revolute = ``radial`` on joint 3), a preset name or a TOML path
    poses : ``(3,)`` or ``(N, 3)`` [x mm, y mm, phi rad]
    search : also find the best feasible configurations (:func:`nonlinear_pose_errors`) for ``lower`` and
        ``gap`` (otherwise NaN)
    allow_outside : accept poses outside the joint ranges (as :func:`pmaccuracy.accuracy.bounds.max_pose_errors`)
    on_failure : ``"raise"`` (:class:`~pmaccuracy.errors.CertificationError` naming the pose and why) or
        ``"nan"`` (NaN upper bounds and the reason in ``reason``)
    split, split_gap : where the bound is not certified or its gap to the best feasible value (to the
        first-order value without ``search``) exceeds ``split_gap``, it is computed again over ``2^split``
        pieces of the error set (:func:`_split_bounds`; 0: never) and the smaller valid bound is kept
    refine : bound the poses still above ``split_gap`` again with the tighter box and every row refined (default);
        ``False`` keeps the first batched bound there (valid, looser; with ``split=0, max_pieces=1`` one pass over
        the batch: a map's quick overview)
    ascent : run the local ascent of the best feasible values at every pose (as :func:`nonlinear_pose_errors`);
        by default it runs only where the bound is not yet within ``REFINE_FRACTION * split_gap`` of the values at
        the first-order worst vertices (those are feasible too: ``lower`` is a lower bound either way)
    max_pieces : where the gap still exceeds ``split_gap`` (or there is no certificate), the set is cut
        adaptively (:func:`_branch_and_bound`) until the gap is below ``split_gap`` or ``max_pieces`` pieces
        (:data:`REFUSED_BUDGET` times as many for a pose with no certificate yet) have been bounded (0 or 1:
        never); the smaller valid bound is kept

    Notes
    -----
    Returns a :class:`CertifiedPoseErrors`: ``upper[q] >= `` the maximum over the whole error set of the
    exact pose error (module docstring) ``>= lower[q] >=`` the exact value at the first-order worst vertex.
    Poses outside the ranges or near a singularity are refused first, as by ``max_pose_errors``.

    Example
    -------
    >>> r = certified_pose_errors("aalborg_3ppr", "case1", [0.0, 0.0, 0.0])
    >>> bool(r.first_order["dx"][0] <= r.lower["dx"][0] <= r.upper["dx"][0])
    True
    """
    check_orientations(poses, "poses", poses=True)
    if on_failure not in ("raise", "nan"):
        raise ValueError(f"on_failure must be 'raise' or 'nan', got {on_failure!r}")
    robot, sources, poses = _prepare(robot, clearances, poses)
    fo = max_pose_errors(robot, sources, poses, allow_outside=allow_outside)
    first = {q: np.asarray(getattr(fo, f"{q}_max"), dtype=float).reshape(-1) for q in QUANTITIES}
    sets = error_set(robot, sources)
    model = _build_model(robot, sets, poses)
    if search:  # feasible values first (the exact closure at the first-order worst vertices): they set the targets
        M1 = _first_order_map(model)
        lower, worst, _ = _nonlinear(model, M1, sets, ascend=ascent)
    else:
        lower = {q: np.full(poses.shape[0], np.nan) for q in QUANTITIES}
        worst = {}
    ref = {q: np.where(np.isfinite(lower[q]), lower[q], first[q]) for q in QUANTITIES}
    # the cheap bounds (4) and the unrefined dual bound (5) of every row at once; the interior-point refinement
    # only for the (pose, row) pairs still above REFINE_FRACTION of the allowed gap (every value is a valid bound)
    target = {q: ref[q] * (1 + REFINE_FRACTION * split_gap) for q in QUANTITIES}
    rb = _certify(model, sets, robot.characteristic_length, target=target, lazy_box=True)
    if model.n == 0:  # no error source: the pose does not move, exactly
        rb["upper"] = {q: np.zeros(poses.shape[0]) for q in QUANTITIES}
    rb.update(model=model, sets=sets)
    if search and model.n and not ascent:
        # the local ascent only where the bound is not yet within REFINE_FRACTION * split_gap of those values
        asc = np.flatnonzero(np.any([~(_gap(rb["upper"][q], ref[q]) <= REFINE_FRACTION * split_gap)
                                     for q in QUANTITIES], axis=0))
        if asc.size:
            lo2, w2, _ = _nonlinear(_take_many(model, asc), M1[asc], sets)
            for q in QUANTITIES:
                up = np.isfinite(lo2[q]) & ~(lo2[q] <= lower[q][asc])
                lower[q][asc[up]], worst[q][asc[up]] = lo2[q][up], w2[q][up]
                ref[q] = np.where(np.isfinite(lower[q]), lower[q], first[q])
                target[q] = ref[q] * (1 + REFINE_FRACTION * split_gap)
    # poses still above split_gap (or not certified): the whole set again with the tighter box and every row
    # refined (the full bound of equations (3)-(5)), batched over those poses only; the smaller valid bound is kept
    loose = (rb["reason"] != "") | np.any([_gap(rb["upper"][q], ref[q]) > split_gap for q in QUANTITIES], axis=0)
    idx = np.flatnonzero(loose & (rb["reason"] != "singular loop-closure Jacobian at the commanded pose"))
    if idx.size and model.n and refine:
        full = _certify(_take_many(model, idx), sets, robot.characteristic_length,
                        target={q: target[q][idx] for q in QUANTITIES}, refine_box=True)
        for q in QUANTITIES:
            rb["upper"][q][idx] = np.where(full["certified"], np.fmin(rb["upper"][q][idx], full["upper"][q]),
                                           rb["upper"][q][idx])
        now = full["certified"] & ~rb["certified"][idx]  # certified only with the tighter box: take its box
        for key in ("b", "b_centre"):
            rb[key][idx[now]] = full[key][now]
        rb["reason"][idx[now]] = ""
        rb["certified"][idx[now]] = True
    upper, reason = dict(rb["upper"]), rb["reason"].copy()
    # the whole set's certificate: the parent every piece is checked against (_continues)
    anc_b = np.where(rb["certified"][:, None], rb["b"], np.nan)
    anc_b0 = _point_box(rb["model"], robot.characteristic_length)
    rejected = np.zeros(poses.shape[0], dtype=int)
    if split:
        # poses without a certificate or with a gap above split_gap: bound again over 2^split pieces, keep the
        # smaller of the valid bounds (both hold)
        loose = (reason != "") | np.any([_gap(upper[q], ref[q]) > split_gap for q in QUANTITIES], axis=0)
        idx = np.flatnonzero(loose & (rb["reason"] != "singular loop-closure Jacobian at the commanded pose"))
        if idx.size:
            sp = _split_bounds(_take_many(rb["model"], idx), rb["sets"], robot.characteristic_length, split,
                               rb["M"][idx], anc_b[idx], anc_b0[idx])
            rejected[idx] += sp["rejected"]
            for q in QUANTITIES:
                upper[q][idx] = np.where(sp["certified"], np.fmin(upper[q][idx], sp["upper"][q]), upper[q][idx])
            reason[idx[sp["certified"]]] = ""
        # not certified, or certified but still loose: adaptive cutting (branch and bound) pose by pose until within
        # split_gap, no progress or the budget ends; a refused pose is certified only if every piece is used
        loose = (reason != "") | np.any([_gap(upper[q], ref[q]) > split_gap for q in QUANTITIES], axis=0)
        idx = np.flatnonzero(loose & (rb["reason"] != "singular loop-closure Jacobian at the commanded pose"))
        for k in idx if max_pieces > 1 else ():
            budget = max_pieces * (REFUSED_BUDGET if reason[k] else 1)
            bb = _branch_and_bound(_take(rb["model"], k), rb["sets"], robot.characteristic_length,
                                   {q: ref[q][k] for q in QUANTITIES}, split_gap, budget,
                                   {"b": anc_b[k], "b0": anc_b0[k]}, min_progress=max_pieces)
            rejected[k] += bb["rejected"]
            if all(np.isfinite(bb["upper"][q]) for q in QUANTITIES):
                for q in QUANTITIES:
                    upper[q][k] = np.fmin(upper[q][k], bb["upper"][q])
                reason[k] = ""
            for q in QUANTITIES:
                if search and bb["worst"][q] is not None and not bb["lower"][q] <= lower[q][k]:
                    lower[q][k], worst[q][k] = bb["lower"][q], bb["worst"][q]
    for k in np.flatnonzero(reason != ""):  # refused: say why the continuation cannot be certified
        if rb["reason"][k] != "singular loop-closure Jacobian at the commanded pose":
            budget = max_pieces * REFUSED_BUDGET if split and max_pieces > 1 else 1
            reason[k] = _refusal(_take(model, k), sets, budget)
    if on_failure == "raise" and np.any(reason != ""):
        k = int(np.flatnonzero(reason != "")[0])
        x, y, phi = poses[k]
        raise CertificationError(f"pose {k} (x={x:g} mm, y={y:g} mm, phi={math.degrees(phi):g} deg): {reason[k]}")
    gap = {q: _gap(upper[q], lower[q]) for q in QUANTITIES}
    loose = [(k, q) for q in QUANTITIES for k in np.flatnonzero(gap[q] > GAP_WARNING)]
    if loose:  # valid but loose: said once, for the loosest
        k, q = max(loose, key=lambda kq: gap[kq[1]][kq[0]])
        x, y, phi = poses[k]
        warn([f"certified bound of {q} at pose {k} (x={x:g} mm, y={y:g} mm, phi={math.degrees(phi):g} deg) is "
              f"{gap[q][k] * 100:.3g} % above the best feasible configuration (valid, but loose: the error set is large "
              f"for this pose{'' if len(loose) == 1 else f'; {len(loose)} such bounds'})"])
    return CertifiedPoseErrors(poses=poses, upper=upper, lower=lower, first_order=first, gap=gap,
                               worst=worst, remainder=rb["b"], reason=reason, sets=rb["sets"], rejected=rejected)


def _refusal(model1: _Model, sets, budget: int) -> str:
    """Why the continuation of the commanded assembly of one pose (``model1``) is not certified over the error
    set: the exact closure solved (Newton from the first-order solution, :func:`exact_change`) at the first-order
    worst vertices and their negatives; a vertex where it fails (no closure near the continuation: another
    assembly, or none, is reached inside the set) or where ``J_z`` is near-singular (condition number above
    1e8: a singularity inside the set) is named; otherwise the budget ran out."""
    M = _first_order_map(model1)
    d0 = _first_order_starts(sets, M)[:, 0]  # (4, 1, n)
    cand = np.concatenate([d0, -d0])  # (8, 1, n)
    dz = exact_change(model1, M, cand)
    if not np.all(np.isfinite(dz)):
        return ("the commanded assembly does not continue over the whole error set: the exact closure fails at a "
                "first-order worst configuration (another assembly, or none, is reached inside the set)")
    J = model1.jacobian(np.concatenate([dz, cand], axis=-1), z_only=True)
    with np.errstate(all="ignore"):
        cond = float(np.max(np.linalg.cond(J)))
    if not cond < 1e8:
        return (f"a singularity inside the error set: the loop-closure Jacobian is near-singular at a first-order "
                f"worst configuration (condition number {cond:.3g})")
    where = (f"within up to {budget} pieces of the error set" if budget > 1 else
             "over the uncut error set (split=0 or max_pieces <= 1)")
    return (f"the continuation of the commanded assembly could not be certified {where} (the remainder bound does "
            f"not close or contract on some piece; no failure of the closure or singularity found at its worst "
            f"vertices): a larger max_pieces (--max-pieces) may certify it")


def nonlinear_pose_errors(robot, clearances, poses, *, allow_outside: bool = False, polish: int = 0
                          ) -> CertifiedPoseErrors:
    """The best feasible worst cases of the exact model: local ascent from the first-order worst vertices.

    From the first-order worst configuration of each quantity and its negative
    (:func:`pmaccuracy.model.sources.worst_configuration`, ``worst_signs``), the exact pose is solved
    (Newton on the closure, :func:`exact_change`) and the configuration is replaced by the extreme point of
    the error set that maximizes the linearization of the exact objective at it (``argsupport`` of its exact
    gradient, a successive-linearization ascent that only accepts increases, all poses at once); with
    ``polish`` (iterations) an SLSQP run over the source parameters follows, pose by pose. Every value is
    attained by a feasible configuration (``worst``), so it is a lower bound of the true maximum.

    Returns a :class:`CertifiedPoseErrors` with ``lower`` (the values), ``worst``, ``first_order`` and, when
    the certificate holds, ``upper`` and ``gap`` (NaN otherwise); arguments as :func:`certified_pose_errors`.
    """
    check_orientations(poses, "poses", poses=True)
    robot, sources, poses = _prepare(robot, clearances, poses)
    fo = max_pose_errors(robot, sources, poses, allow_outside=allow_outside)
    rb = remainder_bounds(robot, sources, poses)
    lower, worst, _ = _nonlinear(rb["model"], rb["M"], rb["sets"], polish=polish)
    first = {q: np.asarray(getattr(fo, f"{q}_max"), dtype=float).reshape(-1) for q in QUANTITIES}
    gap = {q: _gap(rb["upper"][q], lower[q]) for q in QUANTITIES}
    return CertifiedPoseErrors(poses=poses, upper=rb["upper"], lower=lower, first_order=first, gap=gap,
                               worst=worst, remainder=rb["b"], reason=rb["reason"], sets=rb["sets"])


def _first_order_map(model: _Model) -> np.ndarray:
    """``M = -J_z^-1 J_delta`` ``(N, 9, n)`` at the commanded configuration (module docstring, equation (2));
    the identity stands in for ``J_z`` where it is singular (those poses are refused by :func:`_certify`)."""
    N = model.z0.shape[0]
    J = model.jacobian(np.zeros((N, 9 + model.n)))
    with np.errstate(all="ignore"):
        cond = np.linalg.cond(J[..., :9])
    ok = np.isfinite(cond) & (cond < 1e12)
    return -np.linalg.solve(np.where(ok[:, None, None], J[..., :9], np.eye(9)), J[..., 9:])


def _gap(upper: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """``(upper - lower) / lower``; 0 where both are 0, NaN where either is NaN."""
    with np.errstate(all="ignore"):
        g = (upper - lower) / lower
    return np.where((upper == 0) & (lower == 0), 0.0, g)
