r"""Error sources of every joint type, and each leg's share of ``A dX = e`` (issue 9's general method).

Hold the actuators. Every error source is a small displacement (a planar twist)
of the part of a leg beyond it. Pairing that twist with the leg's constraint
wrench ``zeta_i = (f, m_O)`` (:meth:`pmaccuracy.model.chain.Chain.screws`) gives the
source's share of row ``i`` of ``A [dp; dphi] = e``. With ``M(c) = m_O - c x f``
the wrench's moment about a point ``c`` (mm; the pairing with a unit rotation
about ``c``), the sources of joint ``k`` of a leg and their largest ``|e_i|``:

=============  ============================================================  ============================================
key            displacement (inserted in the chain at joint k)               largest share of ``|e_i|``
=============  ============================================================  ============================================
``radial``     R clearance: the distal part translates, ``|delta| <= eps``   ``eps |f|``
``angular``    P tilt ``|tau| <= eps`` of the block about its centre         ``eps |M(b_k)|``
               ``b_k`` (below)
``lateral``    P play: the block shifts by ``sigma`` normal to the rail      ``max(eps |f . E e_k|, 2 eps |M(b_k)| / L)``
               and tilts by ``tau`` about its centre ``b_k``, in the
               rhombus ``|L tau +- 2 sigma| <= 2 eps`` (Eq. 16)
``actuator``   actuated joint error ``|dq| <= eps`` (mm or rad)              ``eps |B_ii|``
``position``   tolerance: the joint's centre moved, ``|delta| <= t``         ``t |f|``
``direction``  tolerance: the joint turned about its centre, ``|tau| <= t``  ``t |M(c_k)|``
``length``     tolerance: the link after joint k longer by ``|dl| <= t``     ``t |f . unit(link_k)|``
=============  ============================================================  ============================================

Link-parameter tolerances in polar form, for robots whose files place the legs
by radius and angle (the paper's 3-PPR, Eq. 1 and 9: its ``a, alpha, gamma, r,
psi``); each is a rotation about a point or a translation along a direction:

=======================  ===================================================  ==========================
key (joint)              displacement                                         largest share of ``|e_i|``
=======================  ===================================================  ==========================
``base_radius`` (1)      the leg's base point moved along the line from the   ``t |f . unit(c_1)|``
                         base origin O, ``|da| <= t``
``base_turn`` (1)        the whole leg turned about O, ``|dalpha| <= t``      ``t |M(O)|``
``link_turn`` (P)        the link after a slide turned about its start        ``t |M(c_k + q_k e_k)|``
                         ``c_k + q_k e_k``, ``|dgamma| <= t`` (not the last)
``platform_radius`` (3)  the platform point ``D`` moved along the line from   ``t |f . unit(D - P)|``
                         the platform centre P, ``|dr| <= t``
``platform_turn`` (3)    the platform point turned about P, ``|dpsi| <= t``   ``t |f . E (D - P)|``
=======================  ===================================================  ==========================

(the number in brackets is the joint that carries the key: the first, a slide
that is not the last, the last). These are taken by the first-order layers
(:func:`~pmaccuracy.accuracy.bounds.max_pose_errors`, maps, design comparison,
:func:`worst_configuration`, :func:`first_order_error`); the layers that need
the exact perturbed geometry or interval enclosures refuse them by name
(:func:`refuse_first_order_only`).

The **block** of a P joint is its short member (carriage, bushing, gland),
which the clearance lets shift and tilt on the long one (rail, rod) about its
own centre ``b_k`` (:attr:`pmaccuracy.model.chain.Joint.block_kind`): a *carriage*
travels with the joint value, ``b_k = c_k + q_k e_k`` (the default of an
actuated P joint); a *bushing* sits at the joint's origin on the proximal part,
``b_k = c_k``, and the rod slides through it (the default of a passive P
joint). So the results do not depend on where a file puts a rail's origin.
Manufacturing tolerances (``direction``) turn the joint about its mounting
point ``c_k``, the origin the file gives.

The sources of a leg are independent and symmetric, so ``e_i`` fills
``[-c_i, c_i]`` with ``c_i`` the sum of the shares (:func:`half_widths`), and
the reachable pose errors are the parallelepiped ``A^-1 diag(c) [-1, 1]^3``

.. math::

    e_i = \sum_{s \in \text{leg } i} \langle \zeta_i, \xi_s \rangle\, \delta_s, \qquad
    c_i = \max_{\delta \in \text{sets}} \lvert e_i \rvert = \sum_s h_s\, \lvert \langle \zeta_i, \xi_s
    \rangle \rvert, \qquad \langle (f, m), \text{rotation about } c \rangle = m_P + (P - c) \times f

with ``xi_s`` the unit twist of source ``s`` and ``h_s`` its half-width (the
guide rhombus: the larger of its two vertices' shares); the bounds of every
architecture follow (:func:`pmaccuracy.accuracy.bounds.max_pose_errors`).

For the paper's 3-PPR (Sec. 4.2) the bearing tilt ``delta theta_i`` about
``C_i`` is ``angular`` on the second joint (a bushing at ``C_i``), the guide
play on the actuated guide is ``lateral`` (shift normal to the rail, tilt
about the carriage ``B_i``), and the
revolute clearance at ``D_i`` is ``radial`` on the third joint:
``c_i = eps_theta l_i + max(eps_g |H_d|, 2 eps_g |H_gamma| / L_g) + eps_r``.

Clearance files list each leg's joints, base to platform (lengths mm, angles rad)::

    name = "rpr_demo"
    [[legs]]                        # exactly three
    joints = [
      { radial = 0.02 },
      { actuator = 0.005, angular = 0.0005 },
      { radial = 0.02 },
    ]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from . import _tomlio
from ..errors import ClearanceError, ConfigError
from ..numerics.screws import cross, dot
from . import plausibility
from ..numerics.linalg import inverse_3x3

#: Keys of one joint's table and the joint types they apply to ("A": the actuated joint).
KEYS = {"radial": "RP", "actuator": "A", "angular": "P", "lateral": "P", "block_length": "P",
        "position": "RP", "direction": "RP", "length": "RP", "base_radius": "RP", "base_turn": "RP",
        "link_turn": "P", "platform_radius": "RP", "platform_turn": "RP"}
#: Keys that only one joint of a leg may carry: joint index (0 first, 2 last), or -1 for "any but the last".
PLACES = {"base_radius": 0, "base_turn": 0, "link_turn": -1, "platform_radius": 2, "platform_turn": 2}
#: Link-parameter tolerances in polar form (module docstring), taken by the first-order layers only.
FIRST_ORDER_ONLY = ("base_radius", "base_turn", "link_turn", "platform_radius", "platform_turn")
#: Units of the keys, for messages.
UNITS = {"radial": "mm", "actuator": "mm or rad", "angular": "rad", "lateral": "mm", "block_length": "mm",
         "position": "mm", "direction": "rad", "length": "mm", "base_radius": "mm", "base_turn": "rad",
         "link_turn": "rad", "platform_radius": "mm", "platform_turn": "rad"}
#: Default guide block length L (mm), as in the 3-PPR clearance files.
DEFAULT_BLOCK_LENGTH = 50.0


@dataclass(frozen=True)
class JointErrors:
    """Half-widths of the error sources of one joint (module docstring); all 0 by default.

    radial, lateral, position, length, base_radius, platform_radius : mm;
    angular, direction, base_turn, link_turn, platform_turn : rad;
    actuator : mm (P) or rad (R);  block_length : mm (the guide's L, with ``lateral``)
    """

    radial: float = 0.0
    actuator: float = 0.0
    angular: float = 0.0
    lateral: float = 0.0
    block_length: float = DEFAULT_BLOCK_LENGTH
    position: float = 0.0
    direction: float = 0.0
    length: float = 0.0
    base_radius: float = 0.0
    base_turn: float = 0.0
    link_turn: float = 0.0
    platform_radius: float = 0.0
    platform_turn: float = 0.0

    def scaled(self, factor: float) -> "JointErrors":
        """Every half-width times ``factor`` (the block length is kept)."""
        return JointErrors(**{f.name: getattr(self, f.name) * (1.0 if f.name == "block_length" else factor)
                              for f in fields(self)})


@dataclass(frozen=True)
class ErrorSources:
    """The error sources of a robot: three legs of three :class:`JointErrors`, base to platform."""

    legs: tuple[tuple[JointErrors, JointErrors, JointErrors], ...]
    name: str = "custom"
    KIND: ClassVar[str] = "clearance"

    def __post_init__(self) -> None:
        """Built in Python (not read from a file, whose reader checks it): warn about values in unlikely units
        (:func:`pmaccuracy.model.plausibility.error_sources_messages`)."""
        if plausibility.called_by_user(skip=1):   # the caller of the generated __init__
            try:
                messages = plausibility.error_sources_messages(self, "ErrorSources")
            except (TypeError, ValueError, AttributeError):   # malformed: check() names it
                return
            plausibility.warn(messages, stacklevel=3)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "ErrorSources":
        """Parse the per-joint clearance/tolerance format (module docstring)."""
        _tomlio.reject_unknown(data, {"name", "description", "legs"}, source=source, where="")
        legs = []
        for i, table in enumerate(_tomlio.legs_table(data, source=source), start=1):
            where = f"legs[{i}]"
            _tomlio.reject_unknown(table, {"joints"}, source=source, where=where)
            joints = table.get("joints")
            if not isinstance(joints, list) or not all(isinstance(j, dict) for j in joints):
                raise ClearanceError("must be a list of three tables {key = value, ...}, base to platform",
                                     source=source, key=f"{where}.joints")
            if len(joints) != 3:
                raise ClearanceError(f"exactly three joints are needed (base to platform), found {len(joints)}",
                                     source=source, key=f"{where}.joints")
            parsed = []
            for k, jt in enumerate(joints, start=1):
                jw = f"{where}.joints[{k}]"
                _tomlio.reject_unknown(jt, set(KEYS), source=source, where=jw)
                values = {}
                for key in jt:
                    values[key] = _tomlio.number(jt, key, source=source, where=jw, nonnegative=True)
                if "block_length" in values and values["block_length"] <= 0:
                    raise ClearanceError("must be positive", source=source, key=f"{jw}.block_length")
                parsed.append(JointErrors(**values))
            legs.append(tuple(parsed))
        name = data.get("name", source)
        if not isinstance(name, str):
            raise ConfigError("must be a string", source=source, key="name")
        result = cls(legs=tuple(legs), name=name)

        plausibility.warn(plausibility.error_sources_messages(result, source), stacklevel=2)
        return result

    def to_dict(self) -> dict[str, Any]:
        """The TOML table (only non-default keys)."""
        default = JointErrors()
        legs = []
        for leg in self.legs:
            joints = []
            for j in leg:
                joints.append({f.name: getattr(j, f.name) for f in fields(j)
                               if getattr(j, f.name) != getattr(default, f.name)})
            legs.append({"joints": joints})
        return {"name": self.name, "legs": legs}

    @classmethod
    def from_clearance_set(cls, clearances, tolerances: dict[str, np.ndarray] | None = None) -> "ErrorSources":
        """The 3-PPR clearance format (guide, bearing, revolute per leg), and optionally tolerance intervals on
        the paper's link parameters (Eq. 9), as per-joint sources of the 3-PPR chain
        (:class:`~pmaccuracy.model.legs.PPRLeg`: guide, bearing, revolute).

        ``tolerances`` maps names of Eq. 10 to half-widths ``(3,)`` (mm or rad), one per leg; each becomes the
        source with the same first-order effect (:data:`PPR_TOLERANCE_KEYS`): ``s`` the guide's actuator,
        ``beta`` and ``theta`` the guide's and the bearing's ``direction``, ``d`` the guide's link ``length``,
        ``gamma`` the link's ``link_turn`` about the carriage, ``rho`` the revolute's ``position``, and the
        polar ``a, alpha, r, psi`` as ``base_radius, base_turn, platform_radius, platform_turn``.

        >>> from pmaccuracy.model.clearances import ClearanceSet
        >>> src = ErrorSources.from_clearance_set(ClearanceSet.preset("case1"), {"d": [0.05, 0.0, 0.0]})
        >>> src.legs[0][0].length, src.legs[0][1].angular > 0
        (0.05, True)
        """
        values = [[{}, {}, {}] for _ in range(3)]
        for i in range(3):
            values[i][0].update(lateral=float(clearances.guide_lateral[i]),
                                block_length=float(clearances.guide_block_length[i]))
            values[i][1].update(angular=float(clearances.bearing_angle[i]))
            values[i][2].update(radial=float(clearances.revolute_radial[i]))
        for name, half_widths in (tolerances or {}).items():
            k, key = PPR_TOLERANCE_KEYS[name]
            for i in range(3):
                values[i][k][key] = float(np.broadcast_to(half_widths, (3,))[i])
        legs = tuple(tuple(JointErrors(**v) for v in leg) for leg in values)
        name = clearances.name if not tolerances else f"{clearances.name} + tolerances"
        return cls(legs=legs, name=name)

    def to_toml(self) -> str:
        """The per-joint clearance file as TOML text."""
        import tomli_w
        return tomli_w.dumps(self.to_dict())

    def scaled(self, factor: float) -> "ErrorSources":
        return ErrorSources(legs=tuple(tuple(j.scaled(factor) for j in leg) for leg in self.legs), name=self.name)

    def check(self, robot) -> "ErrorSources":
        """Refuse sources that do not fit the robot's joints (a key on the wrong joint type), naming leg and joint."""
        if len(self.legs) != 3:
            raise ClearanceError(f"exactly three legs are needed, found {len(self.legs)}", source=self.name,
                                 key="legs")
        for i, (chain, leg) in enumerate(zip(robot.chains, self.legs), start=1):
            for k, (joint, errs) in enumerate(zip(chain.joints, leg), start=1):
                for key, allowed in KEYS.items():
                    value = getattr(errs, key)
                    if not math.isfinite(value) or value < 0:
                        raise ClearanceError(f"must be finite and >= 0, got {value}", source=self.name,
                                             key=f"legs[{i}].joints[{k}].{key}")
                    if key == "block_length" or value == 0:
                        continue
                    ok = (joint.actuated if allowed == "A" else joint.kind in allowed)
                    if not ok:
                        what = "the actuated joint" if allowed == "A" else \
                            {"P": "prismatic joints", "RP": "any joint"}[allowed]
                        raise ClearanceError(
                            f"{key} applies to {what}; joint {k} of leg {i} is a "
                            f"{'actuated ' if joint.actuated else 'passive '}{joint.kind} joint",
                            source=self.name, key=f"legs[{i}].joints[{k}].{key}")
                    self._check_place(chain, i, k, key)
        return self

    def _check_place(self, chain, i: int, k: int, key: str) -> None:
        """Refuse a polar key on a joint that cannot carry it, or where its direction is undefined."""
        if key not in PLACES:
            return
        where = f"legs[{i}].joints[{k}].{key}"
        place = PLACES[key]
        wanted = {0: "the first joint (the leg's base point)", 2: "the last joint (the platform point)",
                  -1: "a slide that is not the last joint"}[place]
        if (place == -1 and k == 3) or (place >= 0 and k != place + 1):
            raise ClearanceError(f"{key} applies to {wanted}, not joint {k}", source=self.name, key=where)
        if key == "base_radius" and chain.base_z == 0:
            raise ClearanceError(f"leg {i}'s base point is the base origin, so the radial direction is "
                                 "undefined; use position (any direction)", source=self.name, key=where)
        if key == "platform_radius" and chain.platform_z == 0:
            raise ClearanceError(f"leg {i}'s platform point is the platform centre, so the radial direction "
                                 "is undefined; use position (any direction)", source=self.name, key=where)


#: The paper's link parameters (Eq. 10) as per-joint sources of the 3-PPR chain: ``name -> (joint, key)``
#: (:meth:`ErrorSources.from_clearance_set`). ``rho`` is a radius in any direction (the clearance's form).
PPR_TOLERANCE_KEYS = {"a": (0, "base_radius"), "alpha": (0, "base_turn"), "s": (0, "actuator"),
                      "beta": (0, "direction"), "d": (0, "length"), "gamma": (0, "link_turn"),
                      "theta": (1, "direction"), "rho": (2, "position"), "r": (2, "platform_radius"),
                      "psi": (2, "platform_turn")}


def refuse_first_order_only(sources: "ErrorSources", what: str) -> "ErrorSources":
    """``sources`` unchanged, or :class:`~pmaccuracy.errors.ClearanceError` naming the first polar
    link-parameter tolerance (:data:`FIRST_ORDER_ONLY`), which ``what`` does not model."""
    for i, leg in enumerate(sources.legs, start=1):
        for k, joint in enumerate(leg, start=1):
            for key in FIRST_ORDER_ONLY:
                if getattr(joint, key):
                    raise ClearanceError(f"{key} (a link-parameter tolerance) is taken by the first-order bounds "
                                         f"and maps only; {what} does not model it yet", source=sources.name,
                                         key=f"legs[{i}].joints[{k}].{key}")
    return sources


def _leg_states(robot, joints: np.ndarray, poses: np.ndarray) -> tuple:
    """Each leg's :class:`~pmaccuracy.model.chain.LegState` at joint values ``joints (..., 3, 3)`` and poses ``(..., 3)``."""
    return tuple(chain.state_at(joints[..., i, :], poses) for i, chain in enumerate(robot.chains))


def half_widths(robot, sources: ErrorSources, joints: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """``c_i`` (mm), shape ``(..., 3)``: the largest ``|e_i|`` of each leg's sources (module docstring).

    ``joints`` ``(..., 3, 3)`` are the joint values at the poses ``(..., 3)``
    (:func:`pmaccuracy.kinematics.inverse_kinematics`).
    """
    poses = np.asarray(poses, dtype=float)
    return states_half_widths(robot, sources, _leg_states(robot, joints, poses), poses)


def states_half_widths(robot, sources: ErrorSources, states: tuple, poses: np.ndarray) -> np.ndarray:
    """:func:`half_widths` from the legs' states (:func:`pmaccuracy.kinematics.leg_states`), ``(..., 3)`` mm.

    Per joint ``k`` with centre ``c_k``, direction ``e_k``, block centre ``b_k``
    (:func:`block_centre`) and the leg's wrench ``(f, m_P)``: ``M(c) = m_P + (P - c) x f``
    is the moment about ``c``, and the shares of the table in the module docstring add up.
    """
    pz = poses[..., 0] + 1j * poses[..., 1]
    out = np.empty(poses.shape[:-1] + (3,))
    for i, (chain, leg, st) in enumerate(zip(robot.chains, sources.legs, states)):
        f, m_P = st.f, st.m_P
        i_, j_ = chain.passive_indices
        couple = chain.joints[i_].kind == "P" and chain.joints[j_].kind == "P"
        const = 0.0          # shares that do not depend on the pose
        terms = []
        for k, (joint, e) in enumerate(zip(chain.joints, leg)):
            if (e.radial or e.position) and not couple:   # |f| = 1 (a pure couple has f = 0)
                const += e.radial + e.position
            if e.angular or e.lateral:
                m_block = np.abs(m_P + cross(pz - block_centre(joint, st, k), f))
                if e.angular:
                    terms.append(e.angular * m_block)
                if e.lateral:
                    shift = e.lateral * np.abs(cross(st.dirs[k], f))      # f . (E e_k) = e_k x f
                    terms.append(np.maximum(shift, (2 * e.lateral / e.block_length) * m_block))
            for key in SCALAR_KEYS:
                t = getattr(e, key)
                if t and not (key == "length" and joint.link == (0.0, 0.0)):
                    terms.append(t * np.abs(source_coefficient(chain, k, key, st, poses)))
        c = const
        for term in terms:
            c = c + term
        out[..., i] = c
    return out


#: Keys whose source is one signed scalar with a pose-dependent share (:func:`source_coefficient`).
SCALAR_KEYS = ("actuator", "direction", "length") + FIRST_ORDER_ONLY


def source_coefficient(chain, k: int, key: str, st, poses: np.ndarray) -> np.ndarray:
    """Share of ``e_i`` per unit value of the scalar source ``key`` (:data:`SCALAR_KEYS`) of joint ``k``
    (0-based) of a leg in state ``st`` at poses ``(..., 3)`` (signed; the module docstring's table without the
    absolute value): ``actuator`` ``B_ii``, ``direction`` ``M(c_k)``, ``length`` ``f . unit(link_k)`` (0 without
    a link), the polar keys :func:`polar_coefficient`.

    >>> from pmaccuracy.model.legs import Chain, Joint
    >>> chain = Chain(joints=(Joint("R"), Joint("P", actuated=True), Joint("R")))
    >>> st = chain.state(np.array([3.0, 4.0, 0.0]))
    >>> round(float(source_coefficient(chain, 1, "actuator", st, np.array([3.0, 4.0, 0.0]))), 12)
    1.0
    """
    if key == "actuator":
        return st.B
    if key == "direction":
        poses = np.asarray(poses, dtype=float)
        return st.m_P + cross(poses[..., 0] + 1j * poses[..., 1] - st.centres[k], st.f)
    if key == "length":
        link = chain.joints[k].link_z
        return dot(st.f, st.dirs[k] * (link / abs(link))) if link != 0 else np.zeros(np.shape(st.f))
    return polar_coefficient(chain, k, key, st, poses)


def polar_coefficient(chain, k: int, key: str, st, poses: np.ndarray) -> np.ndarray:
    """Share of ``e_i`` per unit value of a polar link-parameter tolerance ``key`` on joint ``k`` (0-based) of a
    leg in state ``st`` at poses ``(..., 3)`` (table in the module docstring; signed, mm or mm/rad).

    With ``P`` the platform centre, ``D = P + Rot(phi) platform`` the platform point and ``M(c)`` the leg
    wrench's moment about ``c``::

        base_radius      f . unit(c_1)            base_turn        M(O)
        link_turn        M(c_k + q_k e_k)         platform_radius  -f . unit(D - P)
        platform_turn    -f . E (D - P)

    (the platform terms: the leg holds ``D``, so the platform centre moves opposite to the point).

    >>> from pmaccuracy.model.legs import Chain, Joint
    >>> chain = Chain(joints=(Joint("R"), Joint("P", actuated=True), Joint("R")), base=(10.0, 0.0))
    >>> st = chain.state(np.array([10.0, 5.0, 0.0]))   # the leg points along +y: f = (0, 1)
    >>> round(float(polar_coefficient(chain, 0, "base_turn", st, np.array([10.0, 5.0, 0.0]))), 9)
    10.0
    """
    poses = np.asarray(poses, dtype=float)
    f, m_P = st.f, st.m_P
    pz = poses[..., 0] + 1j * poses[..., 1]
    if key == "base_radius":
        return dot(f, chain.base_z / abs(chain.base_z))
    if key == "base_turn":
        return m_P + cross(pz, f)
    if key == "link_turn":
        return m_P + cross(pz - (st.centres[k] + st.qs[k] * st.dirs[k]), f)
    tip = np.exp(1j * poses[..., 2]) * chain.platform_z
    if key == "platform_radius":
        return -dot(f, tip / abs(chain.platform_z))
    if key == "platform_turn":
        return -dot(f, 1j * tip)
    raise ValueError(f"not a polar key: {key!r}")


def block_centre(joint, st, k: int):
    """Centre ``b_k`` (complex mm, base frame) of the block of P joint ``k`` in the leg state ``st``
    (:class:`~pmaccuracy.model.chain.LegState`): ``c_k + q_k e_k`` for a carriage, ``c_k`` for a bushing
    (module docstring). A carriage followed by no link is the next frame's origin.

    >>> from pmaccuracy.model.legs import Chain, Joint
    >>> chain = Chain(joints=(Joint("R"), Joint("P", actuated=True), Joint("R")))
    >>> st = chain.state(np.array([3.0, 4.0, 0.0]))
    >>> complex(np.round(block_centre(chain.joints[1], st, 1), 12))
    (3+4j)
    >>> complex(np.round(block_centre(Joint("P", block="bushing"), st, 1), 12))
    0j
    """
    if joint.block_kind == "bushing":
        return st.centres[k]
    if k < 2 and joint.link_z == 0:
        return st.centres[k + 1]
    return st.centres[k] + st.qs[k] * st.dirs[k]


def is_per_joint(data: dict[str, Any]) -> bool:
    """True when a parsed clearance file lists each leg's ``joints`` (this module's format)."""
    legs = data.get("legs")
    return isinstance(legs, list) and any(isinstance(leg, dict) and "joints" in leg for leg in legs)


@dataclass(frozen=True)
class JointDisplacements:
    """Values of the error sources of every joint, arrays ``(..., 3 legs, 3 joints)`` (a configuration).

    Attributes
    ----------
    shift : complex mm, translation of the distal part inserted before the joint (``radial``, ``position``)
    turn : rad, rotation about the joint's centre ``c_k`` inserted before it (``direction``)
    sigma, tau : mm and rad, a slide's block shifted normal to the rail and tilted about its centre ``b_k``
        (``lateral``; :func:`block_centre`)
    dq : mm or rad, actuator error (``actuator``)
    dl : mm, change of the link length after the joint (``length``)
    tilt : rad, a slide's block tilted about its centre ``b_k`` (``angular``)
    """

    shift: np.ndarray
    turn: np.ndarray
    sigma: np.ndarray
    tau: np.ndarray
    dq: np.ndarray
    dl: np.ndarray
    tilt: np.ndarray

    FIELDS: ClassVar[tuple[str, ...]] = ("shift", "turn", "sigma", "tau", "dq", "dl", "tilt")

    @classmethod
    def zeros(cls, shape: tuple[int, ...] = ()) -> "JointDisplacements":
        z = lambda: np.zeros(shape + (3, 3))  # noqa: E731 - a separate array for each field
        return cls(**{k: z().astype(complex) if k == "shift" else z() for k in cls.FIELDS})

    def scaled(self, factor) -> "JointDisplacements":
        """Every value times ``factor`` (a scalar or an array broadcasting against ``(..., 1, 1)``)."""
        f = np.asarray(factor, dtype=float)
        f = f[..., None, None] if f.ndim else f
        return JointDisplacements(*(getattr(self, k) * f for k in self.FIELDS))

    def __neg__(self) -> "JointDisplacements":
        return self.scaled(-1.0)


def worst_configuration(robot, sources: ErrorSources, joints: np.ndarray, poses: np.ndarray,
                        signs: np.ndarray) -> JointDisplacements:
    """The source values making each leg's share ``e_i = t_i c_i`` for signs ``t`` ``(..., 3)``.

    Each source sits at the extreme of its set that moves ``e_i`` the most in the
    direction ``t_i`` (module docstring): a translation along ``t_i f``, a turn
    of sign ``t_i sign(M(c_k))``, a block tilt of sign ``t_i sign(M(b_k))``, the
    guide rhombus vertex that wins (pure shift or pure tilt),
    ``dq = t_i eps sign(B_ii)``, ``dl = t_i t sign(f . link)``.
    ``joints`` ``(..., 3, 3)`` are the joint values at the poses ``(..., 3)``.
    With the signs of a row of ``A^-1`` this is the configuration attaining
    that quantity's maximum (``max_pose_errors(...).worst_signs``).
    """
    poses = np.asarray(poses, dtype=float)
    pz = poses[..., 0] + 1j * poses[..., 1]
    shape = poses.shape[:-1]
    out = {k: np.zeros(shape + (3, 3), dtype=complex if k == "shift" else float) for k in JointDisplacements.FIELDS}
    sgn = lambda x: np.where(np.asarray(x) < 0, -1.0, 1.0)  # noqa: E731
    for i, (chain, leg, st) in enumerate(zip(robot.chains, sources.legs, _leg_states(robot, joints, poses))):
        dirs, f, m_P = st.dirs, st.f, st.m_P
        t = signs[..., i]
        unit_f = np.where(np.abs(f) > 0, f / np.where(np.abs(f) > 0, np.abs(f), 1.0), 0.0)
        for k, (joint, e) in enumerate(zip(chain.joints, leg)):
            if e.radial or e.position:
                out["shift"][..., i, k] += t * (e.radial + e.position) * unit_f   # += : a link turn adds here
            if e.angular or e.lateral:
                b = m_P + cross(pz - block_centre(joint, st, k), f)
                out["tilt"][..., i, k] = t * e.angular * sgn(b)
            if e.lateral:
                a = dot(f, 1j * dirs[k])
                shift_wins = e.lateral * np.abs(a) >= 2 * e.lateral * np.abs(b) / e.block_length
                out["sigma"][..., i, k] = np.where(shift_wins, t * e.lateral * sgn(a), 0.0)
                out["tau"][..., i, k] = np.where(shift_wins, 0.0, t * 2 * e.lateral / e.block_length * sgn(b))
            for key in SCALAR_KEYS:
                if getattr(e, key) and not (key == "length" and joint.link == (0.0, 0.0)):
                    value = t * getattr(e, key) * sgn(source_coefficient(chain, k, key, st, poses))
                    if key in _FIELD_OF:
                        out[_FIELD_OF[key]][..., i, k] += value
                    else:
                        _add_polar(out, chain, i, k, key, value, st, poses)
    return JointDisplacements(**out)


#: The configuration field of each non-polar scalar key.
_FIELD_OF = {"actuator": "dq", "direction": "turn", "length": "dl"}


def _add_polar(out: dict, chain, i: int, k: int, key: str, value: np.ndarray, st, poses: np.ndarray) -> None:
    """Add a polar tolerance's value (:func:`polar_coefficient`) to the fields of a configuration, to first
    order: a turn about a point ``c`` is a turn about the next joint's centre ``c_j`` and a shift
    ``value E (c_j - c)`` of the part beyond it; a point moved on the platform shifts the last joint the
    opposite way."""
    if key == "base_radius":
        out["shift"][..., i, 0] += value * (chain.base_z / abs(chain.base_z))
    elif key == "base_turn":
        out["turn"][..., i, 0] += value
        out["shift"][..., i, 0] += value * 1j * st.centres[0]
    elif key == "link_turn":
        start = st.centres[k] + st.qs[k] * st.dirs[k]
        out["turn"][..., i, k + 1] += value
        out["shift"][..., i, k + 1] += value * 1j * (st.centres[k + 1] - start)
    else:
        tip = np.exp(1j * poses[..., 2]) * chain.platform_z
        step = tip / abs(chain.platform_z) if key == "platform_radius" else 1j * tip
        out["shift"][..., i, 2] += -value * step


def first_order_error(robot, joints: np.ndarray, poses: np.ndarray, config: JointDisplacements) -> np.ndarray:
    """Pose error ``A^-1 e`` ``(..., 3)`` [mm, mm, rad] of given source values (first order).

    ``e_i`` pairs each source's twist with leg ``i``'s constraint wrench
    (module docstring); ``joints`` ``(..., 3, 3)`` at the poses ``(..., 3)``.
    """

    poses = np.asarray(poses, dtype=float)
    pz = poses[..., 0] + 1j * poses[..., 1]
    rows, es = [], []
    for i, (chain, st) in enumerate(zip(robot.chains, _leg_states(robot, joints, poses))):
        centres, dirs, f, m_P, B, A_row = st.centres, st.dirs, st.f, st.m_P, st.B, st.A_row
        e = np.zeros(poses.shape[:-1])
        for k, joint in enumerate(chain.joints):
            e = e + dot(f, config.shift[..., i, k])
            e = e + config.turn[..., i, k] * (m_P + cross(pz - centres[k], f))
            if joint.kind == "P":
                e = e + config.sigma[..., i, k] * dot(f, 1j * dirs[k])
                e = e + (config.tau[..., i, k] + config.tilt[..., i, k]) * (
                    m_P + cross(pz - block_centre(joint, st, k), f))
            if joint.actuated:
                e = e + config.dq[..., i, k] * B
            if joint.link != (0.0, 0.0):
                e = e + config.dl[..., i, k] * dot(f, dirs[k] * joint.link_z / abs(joint.link_z))
        rows.append(A_row)
        es.append(e)
    A = np.stack(rows, axis=-2)
    A_inv, _ = inverse_3x3(A)
    return np.einsum("...ij,...j->...i", A_inv, np.stack(es, axis=-1))
