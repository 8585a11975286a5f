"""Legs of planar parallel manipulators: a chain of three one-DOF joints from the base to the platform.

Every leg, whatever its architecture, is described by one :class:`Chain`
(the general form) and everything above this module is generic: it asks a
leg only for its inverse kinematics, the screws of its joints and the
constraint it puts on the platform when one joint is locked. The designer-
facing leg types (:class:`PPRLeg` of the paper, :class:`RPRLeg`,
:class:`RRRLeg`, :class:`PRRLeg`) only translate their parameters into a
chain; this is the one place where architectures differ.

Chain convention (lengths mm, angles rad; files use degrees)
-------------------------------------------------------------
Start from the leg's base frame ``F0`` (origin ``base``, angle
``base_angle``). Joint ``j = 1, 2, 3`` with value ``q_j``:

* **R**: the frame turns by ``offset_j + q_j`` about its origin (the joint
  centre), then the origin moves by ``Rot(angle) link_j``;
* **P**: the frame turns by ``offset_j``, the origin slides ``q_j`` along the
  new x-axis (the joint direction), then moves by ``Rot(angle) link_j``.

As a rigid transform, ``J_j(q) = Rot(offset_j) M_j(q) Tr(link_j)`` with
``M = Rot(q)`` (R) or ``Tr(q e_x)`` (P). The end frame
``F3 = F0 J_1 J_2 J_3`` is fixed to the platform: its origin is the
platform point ``platform`` (platform frame) and its x-axis makes the angle
``platform_angle`` with the platform's x-axis, so for a pose ``(x, y, phi)``::

    F0 J_1(q_1) J_2(q_2) J_3(q_3) = Tr(p) Rot(phi) Tr(platform) Rot(platform_angle)

Exactly one joint is actuated; the two passive ones leave the platform the
motions of a 2-DOF chain, and the leg constrains it through the wrench
reciprocal to them (:func:`pmaccuracy.numerics.screws.constraint_wrench`).

Working mode. Legs with two inverse-kinematics branches (RRR, PRR, RPR with
offsets, ...) choose one by ``working_mode = sign(B_ii)``, the sign of the
pairing of the leg's constraint wrench with its actuated joint's twist. The
two branches merge where ``B_ii = 0`` (a type-1, serial singularity), so the
sign is constant on a branch. For a 3-RRR this is
``sign(cross(B - A, D - B))`` and for a 3-PRR ``sign(dot(u, D - B))``.

Plane vectors are complex numbers inside this module (:mod:`pmaccuracy.numerics.screws`).
"""


from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import GeometryError
from ..numerics.screws import compose, constraint_wrench, cross, dot, expi, invert, pairing, prismatic_twist, revolute_twist, wrap


INF = math.inf
#: Branches of a leg's inverse kinematics (the +sqrt / -sqrt roots); legs with one solution repeat it.
N_BRANCHES = 2
#: Relative size below which a quantity of a leg's geometry counts as zero (coincident centres, ...).
DEGENERATE = 1e-9


#: The blocks a P joint's clearances may act about (:attr:`Joint.block`).
BLOCKS = ("carriage", "bushing")


def check_block(kind: str, block, *, source: str | None = None, key: str = "block") -> None:
    """Refuse a ``block`` that is not one of :data:`BLOCKS` or that is given for an R joint."""
    if block is None:
        return
    if block not in BLOCKS:
        raise GeometryError(f"must be \"carriage\" or \"bushing\", got {block!r}", source=source, key=key)
    if kind != "P":
        raise GeometryError("only a prismatic joint has a block (carriage or bushing)", source=source, key=key)


@dataclass(frozen=True)
class Joint:
    """A one-DOF joint of a leg chain (see the module docstring for the convention).

    Attributes
    ----------
    kind : ``"R"`` (revolute) or ``"P"`` (prismatic)
    actuated : exactly one joint of a leg is
    offset : rad, turn of the frame before the joint motion
    link : ``(2,)`` mm, vector to the next joint in the frame after the joint
    range : ``(lo, hi)`` rad (R) or mm (P); ``(-inf, inf)`` when unlimited
    block : P joints only: the short member the clearances (``angular``, ``lateral``) act about,
        ``"carriage"`` (it travels with the joint value: centre ``c_k + q_k e_k``) or ``"bushing"`` (fixed on
        the proximal part at the joint's origin ``c_k``; the rod slides through it); ``None``: the default
        of :attr:`block_kind`
    """

    kind: str
    actuated: bool = False
    offset: float = 0.0
    link: tuple[float, float] = (0.0, 0.0)
    range: tuple[float, float] = (-INF, INF)
    block: str | None = None

    @property
    def block_kind(self) -> str | None:
        """The P joint's block: :attr:`block` if given, else ``"carriage"`` for an actuated and ``"bushing"``
        for a passive P joint (the paper's 3-PPR: the guide's carriage at ``B_i``, the bearing at ``C_i``);
        ``None`` for an R joint.

        >>> Joint("P", actuated=True).block_kind, Joint("P").block_kind, Joint("R").block_kind
        ('carriage', 'bushing', None)
        """
        if self.kind != "P":
            return None
        return self.block or ("carriage" if self.actuated else "bushing")

    @property
    def link_z(self) -> complex:
        return complex(self.link[0], self.link[1])

    @property
    def limited(self) -> bool:
        """True when the range restricts the joint (an R range of 360 deg or more does not)."""
        lo, hi = self.range
        if self.kind == "R":
            return bool(np.isfinite(lo) and np.isfinite(hi) and hi - lo < 2 * np.pi)
        return bool(np.isfinite(lo) or np.isfinite(hi))

    def transform(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rigid transform ``J(q) = Rot(offset) M(q) Tr(link)`` as ``(angle, translation)``.

        R: ``(offset + q, exp(i(offset + q)) link)``; P: ``(offset, exp(i offset)(q + link))``.
        """
        q = np.asarray(q, dtype=float)
        if self.kind == "R":
            a = self.offset + q
            return a, expi(a) * self.link_z
        return np.full(q.shape, self.offset), expi(self.offset) * (q + self.link_z)

    def wrap(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Revolute values ``q`` (rad) turned by whole turns into ``[lo, lo + 2 pi)`` of the range (the convention
        of printed joint angles: a range of [130, 310] deg shows 220 deg, not -140); values less than ``tol``
        below ``lo`` stay there. Slides and unlimited revolutes are returned as they are."""
        q = np.asarray(q, dtype=float)
        lo = self.range[0]
        if self.kind != "R" or not np.isfinite(lo):
            return q
        u = q - lo + tol
        return lo + np.mod(u, 2 * np.pi) - tol

    def within(self, q: np.ndarray, tol: float) -> np.ndarray:
        """True where ``q`` lies in the range (R: modulo 2 pi), with slack ``tol`` (rad or mm)."""
        lo, hi = self.range
        q = np.asarray(q, dtype=float)
        if not self.limited:
            return np.isfinite(q)
        if self.kind == "R":
            u = q - lo + tol
            shifted = lo + (u - (2 * np.pi) * np.floor(u * (0.5 / np.pi))) - tol  # in [lo - tol, lo + 2 pi - tol)
            return shifted <= hi + tol
        return (q >= lo - tol) & (q <= hi + tol)


@dataclass(frozen=True)
class Dyad:
    """The constraint of a leg with one joint locked: a rigid link between two passive joints.

    ``kind`` is the passive joint types in chain order (``"RR"``, ``"PR"``,
    ``"RP"``, ``"PP"``). The first passive joint's frame ``Lb`` is fixed in the
    base (``base_angle``, ``base_point``), the second's ``Pf`` in the platform
    (``platform_angle``, ``platform_point``), and ``Lb^-1 Pf = Q_i C Q_j`` with
    the fixed transform ``C = (c_angle, c_trans)`` between them (arrays of the
    locked value's shape). At a pose, with ``c0 = exp(i phi) platform_point - base_point``:

    * RR: ``|p + c0| = |c_trans|`` (a circle);
    * PR: ``n . (p + c0) = Im(c_trans)``, ``n = E exp(i base_angle)`` (a line fixed in the base);
    * RP: ``n . (p + c0) = c_trans . E exp(i c_angle)``, ``n = E exp(i (phi + platform_angle))``;
    * PP: ``phi + platform_angle - base_angle = c_angle`` (mod 2 pi).
    """

    kind: str
    base_angle: np.ndarray
    base_point: np.ndarray
    platform_angle: np.ndarray
    platform_point: np.ndarray
    c_angle: np.ndarray
    c_trans: np.ndarray

    def quadric(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The constraint as ``kappa |p|^2 + g . p + h = 0`` at orientations ``phi``.

        Returns ``kappa`` (0 or 1), ``g`` (complex, mm^0 or mm) and ``h`` (mm or
        mm^2), broadcast over ``phi`` and the locked values (PP: ``g = 0`` and
        ``h = sin`` of the angle residual, rad).
        """
        phi = np.asarray(phi, dtype=float)
        c0 = expi(phi) * self.platform_point - self.base_point
        if self.kind == "RR":
            return 1.0, 2 * c0, np.abs(c0) ** 2 - np.abs(self.c_trans) ** 2
        if self.kind == "PR":
            n = 1j * expi(self.base_angle) * np.ones_like(c0)
            return 0.0, n, dot(n, c0) - np.imag(self.c_trans)
        if self.kind == "RP":
            n = 1j * expi(phi + self.platform_angle)
            return 0.0, n, dot(n, c0) - dot(self.c_trans, 1j * expi(self.c_angle))
        residual = phi + self.platform_angle - self.base_angle - self.c_angle
        return 0.0, np.zeros_like(c0), np.sin(residual) + 0 * c0.real

    def quadric_dphi(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Derivatives ``(dg/dphi, dh/dphi)`` of :meth:`quadric`, for Newton steps in ``(x, y, phi)``."""
        phi = np.asarray(phi, dtype=float)
        c0 = expi(phi) * self.platform_point - self.base_point
        dc0 = 1j * expi(phi) * self.platform_point
        if self.kind == "RR":
            return 2 * dc0, 2 * dot(c0, dc0)
        if self.kind == "PR":
            n = 1j * expi(self.base_angle)
            return np.zeros_like(c0), dot(n, dc0)
        if self.kind == "RP":
            n = 1j * expi(phi + self.platform_angle)
            return 1j * n, dot(1j * n, c0) + dot(n, dc0)
        residual = phi + self.platform_angle - self.base_angle - self.c_angle
        return np.zeros_like(c0), np.cos(residual) + 0 * c0.real


@dataclass(frozen=True)
class Curve:
    """A boundary candidate of a constant-orientation workspace: a circle or a line in (x, y), mm.

    Circle: ``|p - centre| = radius``. Line: ``normal . p + offset = 0`` with
    ``|normal| = 1`` (complex ``normal``). ``label`` says which limit it comes from.
    """

    kind: str  # "circle" | "line"
    centre: complex = 0j
    radius: float = 0.0
    normal: complex = 0j
    offset: float = 0.0
    label: str = ""


@dataclass(frozen=True)
class LegState:
    """One leg evaluated at a batch of poses (the data of one evaluation; :meth:`Chain.state`).

    Attributes (leading shape ``(...)`` of the poses)
    -------------------------------------------------
    qs : three ``(...)`` joint values base to platform (mm for P, rad for R in ``(-pi, pi]``), NaN out of
        reach; :attr:`q` stacks them ``(..., 3)``
    centres : three ``(...)`` complex (mm): the frame origin before each joint (an R joint's centre), base frame
    dirs : three ``(...)`` complex unit vectors: each joint's x-axis (a P joint's direction), base frame
    f : ``(...)`` complex: the unit constraint force of the two passive joints (0 for two passive slides)
    m_P : ``(...)`` mm: its moment about the platform centre P (1 for a pure couple)
    B : ``(...)``: ``B_ii``, its pairing with the actuated joint's unit twist (mm for R, 1 for P)

    Row ``i`` of ``A`` is ``[f_x, f_y, m_P]`` (:attr:`A_row`), so ``A [dp; dphi] = B_ii dq_actuated``.
    A field that does not depend on the pose (a 3-PPR's wrench force, a base joint's centre) is kept as a
    scalar, so that the arithmetic on it stays scalar; :attr:`shape` gives the poses' shape.
    """

    qs: tuple
    centres: tuple
    dirs: tuple
    f: np.ndarray
    m_P: np.ndarray
    B: np.ndarray

    @cached_property
    def shape(self) -> tuple:
        """The leading shape ``(...)`` of the poses (a constant field may be stored as a scalar)."""
        return np.broadcast_shapes(*(np.shape(v) for v in (*self.qs, *self.centres, *self.dirs, self.f, self.m_P,
                                                             self.B)))

    @cached_property
    def q(self) -> np.ndarray:
        """``(..., 3)`` the joint values stacked."""
        return np.stack([np.broadcast_to(v, self.shape) for v in self.qs], axis=-1)

    @property
    def A_row(self) -> np.ndarray:
        """``(..., 3)``: ``[f_x, f_y, m_P]``, the leg's row of ``A`` (Eq. 4a in general form)."""
        return np.stack([np.broadcast_to(v, self.shape) for v in (np.real(self.f), np.imag(self.f), self.m_P)],
                        axis=-1)

    def where(self, mask: np.ndarray, other: "LegState") -> "LegState":
        """This state where ``mask`` is False and ``other`` where it is True (elementwise)."""
        pick = lambda a, b: np.where(mask, b, a)  # noqa: E731
        return LegState(qs=tuple(pick(a, b) for a, b in zip(self.qs, other.qs)),
                        centres=tuple(pick(a, b) for a, b in zip(self.centres, other.centres)),
                        dirs=tuple(pick(a, b) for a, b in zip(self.dirs, other.dirs)),
                        f=pick(self.f, other.f), m_P=pick(self.m_P, other.m_P), B=pick(self.B, other.B))


@dataclass(frozen=True)
class Chain:
    """A leg as a chain of three one-DOF joints (general form; module docstring).

    Attributes
    ----------
    joints : three :class:`Joint`, base to platform, exactly one actuated
    base : ``(2,)`` mm and ``base_angle`` rad: the leg's base frame ``F0``
    platform : ``(2,)`` mm and ``platform_angle`` rad: the end frame in the platform frame
    working_mode : +1 or -1, the sign of ``B_ii`` on the chosen IK branch
    """

    joints: tuple[Joint, Joint, Joint]
    base: tuple[float, float] = (0.0, 0.0)
    base_angle: float = 0.0
    platform: tuple[float, float] = (0.0, 0.0)
    platform_angle: float = 0.0
    working_mode: int = 1

    def __post_init__(self) -> None:
        if len(self.joints) != 3:
            raise GeometryError(f"a leg needs exactly three joints, got {len(self.joints)}", key="joints")
        for j, joint in enumerate(self.joints, start=1):
            if joint.kind not in ("R", "P"):
                raise GeometryError(f"joint type must be 'R' or 'P', got {joint.kind!r}", key=f"joints[{j}].type")
        n_act = sum(joint.actuated for joint in self.joints)
        if n_act != 1:
            raise GeometryError(f"exactly one joint must be actuated, found {n_act}", key="joints")
        for j, joint in enumerate(self.joints, start=1):
            check_block(joint.kind, joint.block, key=f"joints[{j}].block")
        if self.pattern == "PPP":
            raise GeometryError("a P-P-P leg cannot let the platform turn: at least one joint must be revolute",
                                key="joints")
        if self.working_mode not in (1, -1):
            raise GeometryError(f"must be +1 or -1, got {self.working_mode!r}", key="working_mode")
        self._check_degenerate()

    # ------------------------------------------------------------------ structure
    @property
    def pattern(self) -> str:
        """Joint types base to platform, e.g. ``"RPR"``."""
        return "".join(joint.kind for joint in self.joints)

    @property
    def label(self) -> str:
        """The pattern with the actuated joint marked by an underscore after it, e.g. ``"RP_R"``."""
        return "".join(j.kind + ("_" if j.actuated else "") for j in self.joints)

    @property
    def actuated_index(self) -> int:
        return next(k for k, joint in enumerate(self.joints) if joint.actuated)

    @property
    def passive_indices(self) -> tuple[int, int]:
        a = self.actuated_index
        i, j = (k for k in range(3) if k != a)
        return i, j

    @property
    def actuated(self) -> Joint:
        return self.joints[self.actuated_index]

    @cached_property
    def _offsets_cum(self) -> np.ndarray:
        return np.cumsum([joint.offset for joint in self.joints])

    @cached_property
    def _links(self) -> np.ndarray:
        return np.array([joint.link_z for joint in self.joints])

    @property
    def base_z(self) -> complex:
        return complex(*self.base)

    @property
    def platform_z(self) -> complex:
        return complex(*self.platform)

    @property
    def n_branches(self) -> int:
        """Number of distinct inverse-kinematics solutions of a generic pose (1 or 2)."""
        return 1 if self.pattern.count("R") == 1 else 2

    def _scale(self) -> float:
        return max(1.0, abs(self.base_z), abs(self.platform_z), *(abs(v) for v in self._links))

    def _check_degenerate(self) -> None:
        """Refuse chains whose inverse kinematics is undefined everywhere (coincident revolutes, zero links)."""
        rs = [k for k, joint in enumerate(self.joints) if joint.kind == "R"]
        tiny = DEGENERATE * self._scale()
        if len(rs) == 3:
            for k in (0, 1):
                if abs(self._links[k]) <= tiny:
                    raise GeometryError("three revolute joints need non-zero links between the first and "
                                        "second and the second and third joint (coincident centres)",
                                        key=f"joints[{k + 1}].link")
        if len(rs) == 2:
            m, n = rs
            k = 3 - m - n
            if not m <= k < n and abs(self._rotating_part(m, n)) <= tiny:
                raise GeometryError("the two revolute joints are concentric (coincident points): the leg "
                                    "cannot place the platform", key=f"joints[{n + 1}]")
        if len(rs) == 1:
            ps = [k for k in range(3) if k != rs[0]]
            between = ps[0] < rs[0] < ps[1]
            if not between:
                oc = self._offsets_cum
                if abs(np.sin(oc[ps[1]] - oc[ps[0]])) <= 1e-6:
                    raise GeometryError("the two prismatic joints are parallel: the leg cannot place the "
                                        "platform", key=f"joints[{ps[1] + 1}].offset_deg")

    def _rotating_part(self, m: int, n: int) -> complex:
        oc = self._offsets_cum
        return complex(sum(np.exp(1j * oc[j]) * self._links[j] for j in range(m, n)))

    # ------------------------------------------------------------------ forward evaluation
    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Joint screws' geometry for joint values ``q (..., 3)`` (mm / rad), in the base frame.

        Returns ``centres (..., 3)`` complex mm (frame origin before each joint:
        the centre of an R joint), ``directions (..., 3)`` complex unit (x-axis
        after each joint's offset: the direction of a P joint), and the end
        frame's ``angle (...)`` rad and ``origin (...)`` complex mm.
        """
        q = np.asarray(q, dtype=float)
        angle = np.full(q.shape[:-1], float(self.base_angle))
        pos = np.full(q.shape[:-1], self.base_z, dtype=complex)
        centres, dirs = [], []
        for k, joint in enumerate(self.joints):
            centres.append(pos)
            if joint.kind == "R":
                angle = angle + joint.offset + q[..., k]
                dirs.append(expi(angle))
                pos = pos + expi(angle) * joint.link_z
            else:
                angle = angle + joint.offset
                e = expi(angle)
                dirs.append(e)
                pos = pos + e * (q[..., k] + joint.link_z)
        return np.stack(centres, axis=-1), np.stack(dirs, axis=-1), angle, pos

    def screws(self, q: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row of ``A`` and entry ``B_ii`` of this leg (paper Eq. 3-4 in general form).

        With the constraint wrench ``zeta = (f, m_O)`` of the passive joints
        (:func:`~pmaccuracy.numerics.screws.constraint_wrench`) at joint values ``q (..., 3)``
        and poses ``(..., 3)``::

            A_i = [f_x, f_y, m_O - p x f]      (moment about the platform centre P: mm)
            B_ii = zeta . T_actuated          (mm for an actuated R, 1 for an actuated P)

        so that ``A_i [p_dot; phi_dot] = B_ii q_dot_actuated``.

        Returns ``A_row (..., 3)`` and ``B (...)``.
        """
        centres, dirs, _, _ = self.frames(q)
        i, j = self.passive_indices
        kinds = (self.joints[i].kind, self.joints[j].kind)
        f, m = constraint_wrench(kinds, (centres[..., i], centres[..., j]), (dirs[..., i], dirs[..., j]))
        p = np.asarray(poses, dtype=float)
        pz = p[..., 0] + 1j * p[..., 1]
        a = self.actuated_index
        twist = revolute_twist(centres[..., a]) if self.joints[a].kind == "R" else prismatic_twist(dirs[..., a])
        B = pairing((f, m), twist)
        A_row = np.stack([f.real, f.imag, m - cross(pz, f)], axis=-1)
        return A_row, B

    # ------------------------------------------------------------------ inverse kinematics
    def ik_branches(self, poses: np.ndarray) -> np.ndarray:
        """Both inverse-kinematics branches: joint values ``(..., 2, 3)`` (mm / rad), NaN where unreachable.

        With the target end frame in the leg's base frame, ``g`` (origin) and
        ``gamma`` (angle), the revolute values add up to
        ``S = gamma - sum(offsets)``; the rest is closed-form by the number of
        revolute joints:

        * one R: every direction is known and the two slides solve
          ``q_a e_a + q_b e_b = g - sum Rot(theta_k) link_k`` (2x2, one solution);
        * two R (``m < n``) and a P (``k``): with ``t = q_m``, the links between
          the revolutes turn with ``t``: ``Rot(t) V`` (``V`` their sum at t = 0).
          If the slide lies between them, ``|V + q e_k| = |W|``, otherwise
          ``|W - q e_k| = |V|``: a quadratic in ``q`` (two branches), then ``t``
          from the angle of the matched vectors;
        * three R: the wrist ``W = g - Rot(gamma) link_3`` and the two-link
          law of cosines (two branches, elbow up and down).

        R values are wrapped to ``(-pi, pi]``. Branch 0 takes ``+sqrt``.
        """
        poses = np.asarray(poses, dtype=float)
        phi = poses[..., 2]
        pz = poses[..., 0] + 1j * poses[..., 1]
        g = expi(-self.base_angle) * (pz + expi(phi) * self.platform_z - self.base_z)
        gamma = phi + self.platform_angle - self.base_angle
        oc = self._offsets_cum
        links = self._links
        S = gamma - oc[2]
        rs = [k for k, joint in enumerate(self.joints) if joint.kind == "R"]
        shape = phi.shape + (N_BRANCHES, 3)
        q = np.full(shape, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            if len(rs) == 1:
                m = rs[0]
                theta = [oc[k] + (S if k >= m else 0.0) for k in range(3)]
                rhs = g - sum(expi(theta[k]) * links[k] for k in range(3))
                a, b = (k for k in range(3) if k != m)
                ea, eb = expi(theta[a]), expi(theta[b])
                den = cross(ea, eb)
                den = np.where(np.abs(den) > 1e-12, den, np.nan)
                q[..., :, a] = (cross(rhs, eb) / den)[..., None]
                q[..., :, b] = (cross(ea, rhs) / den)[..., None]
                q[..., :, m] = wrap(S)[..., None]
            elif len(rs) == 2:
                m, n = rs
                k = 3 - m - n
                fixed = sum(expi(oc[j] + (S if j >= n else 0.0)) * links[j] for j in range(3) if j < m or j >= n)
                V = self._rotating_part(m, n)
                W = g - fixed
                sign = np.array([1.0, -1.0])
                if m <= k < n:
                    ek = np.exp(1j * oc[k])
                    disc = np.abs(W) ** 2 - cross(V, ek) ** 2
                    root = np.sqrt(_clip_disc(disc, np.abs(W) ** 2))
                    qk = -dot(V, ek) + sign * root[..., None]
                    t = np.angle(W)[..., None] - np.angle(V + qk * ek)
                else:
                    ek = expi(oc[k] + (S if k >= n else 0.0 * S))
                    disc = abs(V) ** 2 - cross(W, ek) ** 2
                    root = np.sqrt(_clip_disc(disc, abs(V) ** 2))
                    qk = dot(W, ek)[..., None] + sign * root[..., None]
                    t = np.angle(W[..., None] - qk * ek[..., None]) - np.angle(V)
                q[..., :, k] = qk
                q[..., :, m] = wrap(t)
                q[..., :, n] = wrap(S[..., None] - t)
            else:
                l1, l2, l3 = links
                W = g - expi(gamma) * l3
                L1, L2 = abs(l1), abs(l2)
                c = (np.abs(W) ** 2 - L1 ** 2 - L2 ** 2) / (2 * L1 * L2)
                c = np.where(np.abs(c) <= 1 + 1e-12, np.clip(c, -1, 1), np.nan)
                beta = np.stack([np.arccos(c), -np.arccos(c)], axis=-1)
                rel = beta + np.angle(l1) - np.angle(l2)          # t2 - t1, angle between the link frames
                t1 = np.angle(W)[..., None] - np.angle(l1 + expi(rel) * l2)
                q1 = t1 - oc[0]
                q2 = rel - self.joints[1].offset
                q[..., :, 0] = wrap(q1)
                q[..., :, 1] = wrap(q2)
                q[..., :, 2] = wrap(S[..., None] - q1 - q2)   # q1 + q2 + q3 = gamma - o1 - o2 - o3 = S
        return q

    # ------------------------------------------------------------------ one evaluation (lean path)
    @cached_property
    def _branch(self) -> float:
        """The sign of the square root (``+1`` or ``-1`` in :meth:`ik_branches`) whose branch has
        ``sign(B_ii) = working_mode``.

        ``B_ii`` vanishes only where the two branches merge, so the sign is the
        same on a whole branch: it is read once at a pose built by forward
        evaluation of generic joint values. :meth:`state` still checks every pose
        and takes the other root where this guess does not hold.
        """
        if self.n_branches == 1:
            return 1.0
        scale = self._scale()
        q = np.array([0.61 if j.kind == "R" else 0.37 * scale for j in self.joints])
        _, _, angle, origin = self.frames(q)
        attach = complex(origin) - np.exp(1j * (float(angle) - self.platform_angle)) * self.platform_z
        pose = np.array([attach.real, attach.imag, float(angle) - self.platform_angle])
        for sigma in (1.0, -1.0):
            B = self._solve(pose[None, :], sigma).B
            if np.isfinite(B[0]) and B[0] * self.working_mode > 0:
                return sigma
        return 1.0

    def _solve(self, poses: np.ndarray, sigma: float, e_phi: np.ndarray | None = None,
               pz: np.ndarray | None = None, phi: np.ndarray | float | None = None) -> "LegState":
        """The IK branch with root sign ``sigma`` and its geometry, without trigonometry beyond one ``arctan2``
        per revolute angle (:meth:`state`)."""
        if phi is None:
            phi = poses[..., 2]
        if e_phi is None:
            e_phi = np.cos(phi) + 1j * np.sin(phi)
        if pz is None:
            pz = poses[..., 0] + 1j * poses[..., 1]
        eb = complex(np.exp(1j * self.base_angle))
        ebc = eb.conjugate()
        # end origin in the leg frame: conj(eb) (p + e_phi platform - base), as few array operations as possible
        g = (pz if eb == 1 else ebc * pz) + (e_phi * (ebc * self.platform_z) if self.platform_z != 0 else 0.0)
        if self.base_z != 0:
            g = g - ebc * self.base_z
        oc = self._offsets_cum
        links = self._links
        rot = [complex(np.exp(1j * o)) for o in oc]
        turn = complex(np.exp(1j * (self.platform_angle - self.base_angle)))     # exp(i gamma) = e_phi turn
        E_S = e_phi * (turn * rot[2].conjugate())                                # exp(i S), S = gamma - o1-o2-o3
        S = phi + (self.platform_angle - self.base_angle - oc[2])
        rs = [k for k, joint in enumerate(self.joints) if joint.kind == "R"]
        q: list[Any] = [None, None, None]
        d: list[Any] = [None, None, None]   # joint directions in the leg frame
        with np.errstate(invalid="ignore", divide="ignore"):
            if len(rs) == 1:
                m = rs[0]
                d = [rot[k] * E_S if k >= m else rot[k] for k in range(3)]
                rhs = g - sum(d[k] * links[k] for k in range(3) if links[k] != 0)
                a, b = (k for k in range(3) if k != m)
                den = cross(d[a], d[b])
                den = np.where(np.abs(den) > 1e-12, den, np.nan)
                q[a] = cross(rhs, d[b]) / den
                q[b] = cross(d[a], rhs) / den
                q[m] = wrap(S)
            elif len(rs) == 2:
                m, n = rs
                k = 3 - m - n
                fixed = sum(rot[j] * links[j] for j in range(m)) + \
                    sum(rot[j] * links[j] for j in range(n, 3)) * E_S
                V = self._rotating_part(m, n)
                W = g - fixed
                if m <= k < n:
                    ek = rot[k]
                    W2 = W.real ** 2 + W.imag ** 2
                    root = _root(W2 - cross(V, ek) ** 2, W2)
                    qk = -dot(V, ek) + sigma * root
                    E_t = W * np.conj(V + qk * ek) * (1.0 / W2)     # (no complex division: slow)
                else:
                    ek = rot[k] * E_S if k >= n else rot[k]
                    V2 = abs(V) ** 2
                    root = _root(V2 - cross(W, ek) ** 2, V2)
                    qk = dot(W, ek) + sigma * root
                    E_t = (W - qk * ek) * (V.conjugate() / V2)
                q[k] = qk
                q[m] = np.angle(E_t)
                q[n] = wrap(S - q[m])
                d = [rot[j] if j < m else rot[j] * E_t if j < n else rot[j] * E_S for j in range(3)]
            else:
                l1, l2, l3 = links
                L1, L2 = abs(l1), abs(l2)
                E_g = e_phi * turn                                               # exp(i gamma)
                W = g - E_g * l3
                W2 = W.real ** 2 + W.imag ** 2
                c = (W2 - L1 ** 2 - L2 ** 2) / (2 * L1 * L2)
                c = np.where(np.abs(c) <= 1 + 1e-12, np.clip(c, -1.0, 1.0), np.nan)
                beta = sigma * np.arccos(c)
                E_rel = (c + 1j * (sigma * np.sqrt(1.0 - c * c))) * complex(l1 / L1 * (l2 / L2).conjugate())
                E_t1 = W * np.conj(l1 + E_rel * l2) * (1.0 / W2)
                q[0] = np.angle(E_t1 * rot[0].conjugate())
                q[1] = wrap(beta + (np.angle(l1) - np.angle(l2) - self.joints[1].offset))
                q[2] = wrap(S - q[0] - q[1])
                d = [E_t1, E_t1 * E_rel, E_g]                 # the last frame's angle is gamma
        dirs = tuple(eb * dk for dk in d)
        centres: list[Any] = [self.base_z]
        for k, joint in enumerate(self.joints[:2]):
            if joint.kind == "P":
                centres.append(centres[-1] + dirs[k] * (q[k] + joint.link_z))
            else:
                centres.append(centres[-1] + dirs[k] * joint.link_z if joint.link_z != 0 else centres[-1])
        return self._screw_state(tuple(q), tuple(centres), dirs, pz, tip=e_phi * self.platform_z)

    def _screw_state(self, qs: tuple, centres: tuple, dirs: tuple, pz: np.ndarray, tip=None) -> "LegState":
        """:class:`LegState` from joint values, centres and directions: the constraint wrench of the passive
        joints (:func:`~pmaccuracy.numerics.screws.constraint_wrench`), its moment about P and ``B_ii``.

        ``tip``, the end frame's origin relative to P (``Rot(phi) platform``), lets the moment about P use
        the platform-side joint's position relative to P, which is constant at a constant orientation
        (a 3-PPR's whole row of A is then a constant of the map's layer)."""
        i, j = self.passive_indices
        ki, kj = self.joints[i].kind, self.joints[j].kind
        with np.errstate(invalid="ignore", divide="ignore"):
            if ki == "R" and kj == "R":
                line = centres[i]
                dvec = centres[j] - centres[i]
                f = dvec * (1.0 / np.abs(dvec))
            elif ki == "P" and kj == "P":
                line = None
                f = np.zeros(np.shape(pz), dtype=complex)
            else:
                line = centres[i] if ki == "R" else centres[j]
                f = 1j * (dirs[j] if ki == "R" else dirs[i])
        a = self.actuated_index
        if line is None:                       # a pure couple: m = 1 about every point
            m_P = np.ones(np.shape(pz))
            B = m_P if self.joints[a].kind == "R" else np.zeros(np.shape(pz))
        else:
            last_r = tip is not None and self.joints[2].kind == "R" and (line is centres[2] or j == 2)
            if last_r:              # the force line passes through the last joint: P -> joint 3 = tip - link
                link = self.joints[2].link_z
                m_P = cross(tip - dirs[2] * link if link != 0 else tip, f)
            else:
                m_P = cross(line - pz, f)
            B = cross(line - centres[a], f) if self.joints[a].kind == "R" else dot(f, dirs[a])
        return LegState(qs=qs, centres=centres, dirs=dirs, f=f, m_P=m_P, B=B)

    def state(self, poses: np.ndarray, e_phi: np.ndarray | None = None, pz: np.ndarray | None = None,
              phi: np.ndarray | float | None = None) -> "LegState":
        """The leg at poses ``(..., 3)`` on its working mode: joint values, joint geometry and wrench.

        The closed forms of :meth:`ik_branches` written for one branch, with every
        joint direction obtained from the solution's vectors instead of
        ``exp(i angle)``: one IK, the joint centres and directions, the
        constraint wrench ``(f, m_P)`` and ``B_ii`` (Eq. 2-4 in general form) in
        one pass. ``e_phi``, ``pz`` and ``phi`` may pass ``exp(i phi)``, ``x + i y`` and ``phi`` shared by the
        legs (``phi`` and ``e_phi`` scalars when every pose has the same orientation).
        NaN where the leg cannot reach the pose.

        >>> chain = Chain(joints=(Joint("R"), Joint("P", actuated=True), Joint("R")), platform=(0.0, 0.0))
        >>> st = chain.state(np.array([3.0, 4.0, 0.0]))
        >>> st.q.round(6).tolist(), complex(np.round(st.f, 12)), round(float(st.B), 12)
        ([0.927295, 5.0, -0.927295], (0.6+0.8j), 1.0)
        """
        poses = np.asarray(poses, dtype=float)
        st = self._solve(poses, self._branch, e_phi, pz, phi)
        if self.n_branches == 2:
            wrong = st.B * self.working_mode < 0
            if np.any(wrong):
                other = self._solve(poses, -self._branch, e_phi, pz, phi)
                st = st.where(wrong, other)
        return st

    def state_at(self, q: np.ndarray, poses: np.ndarray) -> "LegState":
        """:class:`LegState` at given joint values ``q (..., 3)`` and poses ``(..., 3)`` (no IK)."""
        q = np.asarray(q, dtype=float)
        centres, dirs, _, _ = self.frames(q)
        p = np.asarray(poses, dtype=float)
        pz = p[..., 0] + 1j * p[..., 1]
        return self._screw_state(tuple(q[..., k] for k in range(3)), tuple(centres[..., k] for k in range(3)),
                                 tuple(dirs[..., k] for k in range(3)), pz)

    def inverse_kinematics(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint values on the working mode's branch: ``q (..., 3)``, ``A_row (..., 3)``, ``B (...)``.

        For legs with two branches the branch with ``sign(B_ii) = working_mode``
        is taken (module docstring); NaN where the pose is out of reach.
        """
        st = self.state(poses)
        return st.q, st.A_row, np.asarray(st.B)

    def within_limits(self, q: np.ndarray, tol: float) -> np.ndarray:
        """True where every joint value ``q (..., 3)`` is within its range (slack ``tol``)."""
        ok = np.ones(np.shape(q)[:-1], dtype=bool)
        for k, joint in enumerate(self.joints):
            ok &= joint.within(q[..., k], tol)
        return ok

    # ------------------------------------------------------------------ locked joints
    def locked(self, k: int, value: np.ndarray | float) -> Dyad:
        """The leg's constraint on the platform with joint ``k`` (0-based) locked at ``value``.

        With the two other joints ``i < j`` passive, and ``J_k`` the locked joint's transform::

            Lb = F0 [J_k if k < i] Rot(offset_i)               (fixed in the base)
            Pf = Tr(p) Rot(phi) Att [J_k^-1 if k > j] Tr(-link_j) (fixed in the platform)
            C  = Tr(link_i) [J_k if i < k < j] Rot(offset_j)

        and ``Lb^-1 Pf = Q_i(q_i) C Q_j(q_j)`` (:class:`Dyad`).
        """
        value = np.asarray(value, dtype=float)
        i, j = (m for m in range(3) if m != k)
        Jk = self.joints[k].transform(value)
        zero = np.zeros(value.shape)
        Lb = (self.base_angle + zero, self.base_z + zero)
        if k < i:
            Lb = compose(Lb, Jk)
        Lb = compose(Lb, (self.joints[i].offset, 0j))
        Pf = (self.platform_angle + zero, self.platform_z + zero)
        if k > j:
            Pf = compose(Pf, invert(Jk))
        Pf = compose(Pf, (0.0, -self.joints[j].link_z))
        C = (zero, self.joints[i].link_z + zero)
        if i < k < j:
            C = compose(C, Jk)
        C = compose(C, (self.joints[j].offset, 0j))
        kind = self.joints[i].kind + self.joints[j].kind
        return Dyad(kind=kind, base_angle=Lb[0], base_point=Lb[1], platform_angle=Pf[0], platform_point=Pf[1],
                    c_angle=C[0], c_trans=C[1])

    def boundary_curves(self, phi: float) -> list[Curve]:
        """Every curve that can bound this leg's reachable positions at orientation ``phi`` (rad).

        * each finite joint limit ``q_k = lo, hi``: the locked leg's constraint
          (:meth:`locked`) is a circle (RR) or a line (PR, RP); PP gives none;
        * where the two IK branches merge (``B_ii = 0``): for three R, circles
          ``|wrist - F0| = |l1| +- |l2|``; for two R and a P between them, the
          circle ``|W| = |V x e_k|``; otherwise the two lines ``W x e_k = +-|V|``
          (notation of :meth:`ik_branches`).
        """
        curves: list[Curve] = []
        tiny = DEGENERATE * self._scale()
        for k, joint in enumerate(self.joints):
            if not joint.limited:
                continue
            for bound, name in ((joint.range[0], "min"), (joint.range[1], "max")):
                if not np.isfinite(bound):
                    continue
                dy = self.locked(k, bound)
                curve = _dyad_curve(dy, phi, f"q{k + 1} = {name}")
                if curve is not None:
                    curves.append(curve)
        # branch boundaries, written as |p + c| = radius or n . p + h = 0 (see ik_branches)
        rs = [k for k, joint in enumerate(self.joints) if joint.kind == "R"]
        oc = self._offsets_cum
        links = self._links
        rot_phi = np.exp(1j * phi)
        if len(rs) == 3:
            d_w = self.platform_z - np.exp(1j * self.platform_angle) * links[2]
            centre = self.base_z - rot_phi * d_w
            for radius in (abs(links[0]) + abs(links[1]), abs(abs(links[0]) - abs(links[1]))):
                if radius > tiny:
                    curves.append(Curve("circle", centre=complex(centre), radius=float(radius), label="branch"))
        elif len(rs) == 2:
            m, n = rs
            k = 3 - m - n
            base_rot = np.exp(1j * self.base_angle)
            # W (leg frame) = p + Rot(phi) d_w - b_w (base frame), rotated by -base_angle
            d_w = self.platform_z - sum(np.exp(1j * (self.platform_angle + oc[j] - oc[2])) * links[j]
                                        for j in range(n, 3))
            b_w = self.base_z + base_rot * sum(np.exp(1j * oc[j]) * links[j] for j in range(0, m))
            c = rot_phi * d_w - b_w
            V = self._rotating_part(m, n)
            if m <= k < n:
                radius = abs(cross(V, np.exp(1j * oc[k])))
                if radius > tiny:
                    curves.append(Curve("circle", centre=complex(-c), radius=float(radius), label="branch"))
            else:
                e = base_rot * np.exp(1j * oc[k]) if k < m else np.exp(1j * (phi + self.platform_angle + oc[k] - oc[2]))
                normal = -1j * e          # cross(p, e) = (-i e) . p
                for s in (1.0, -1.0):
                    curves.append(Curve("line", normal=complex(normal), offset=float(cross(c, e) - s * abs(V)),
                                        label="branch"))
        return curves


def _root(disc: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """``sqrt(disc)`` where a discriminant that rounding pushed just below 0 counts as 0 and a clearly
    negative one gives NaN (as :func:`_clip_disc`, without temporaries of the whole size)."""
    root = np.sqrt(np.maximum(disc, 0.0))
    bad = disc < -1e-12 * np.maximum(scale, 1.0)
    if np.ndim(root) == 0:
        return np.float64(np.nan) if bad else root
    if bad.any():
        root[bad] = np.nan
    return root


def _clip_disc(disc: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """A discriminant that rounding pushed just below 0 at a tangency is 0; clearly negative ones are NaN."""
    tol = 1e-12 * np.maximum(scale, 1.0)
    return np.where(disc >= -tol, np.maximum(disc, 0.0), np.nan)


def _dyad_curve(dy: Dyad, phi: float, label: str) -> Curve | None:
    kappa, g, h = dy.quadric(phi)
    g, h = complex(np.asarray(g)), float(np.asarray(h))
    if dy.kind == "RR":
        return Curve("circle", centre=complex(-g / 2), radius=float(abs(complex(dy.c_trans))), label=label)
    if dy.kind in ("PR", "RP"):
        norm = abs(g)
        return Curve("line", normal=g / norm, offset=h / norm, label=label)
    return None


# ====================================================================== designer leg types
