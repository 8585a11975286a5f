"""Planar serial arms: forward kinematics and exact worst-case end-effector errors (issue 9, item 5).

Convention (lengths mm, angles rad; files use degrees)
------------------------------------------------------
The frame starts at the base origin with angle 0. Joint ``k = 1 .. n`` with
value ``q_k`` and link ``length_k``:

* **R**: the frame turns by ``offset_k + q_k`` about its origin (the joint's
  centre ``c_k``), then the origin moves ``length_k`` along the new x-axis;
* **P**: the frame turns by ``offset_k``, then the origin slides
  ``q_k + length_k`` along the new x-axis (the slide's direction ``e_k``); the
  link of ``length_k`` runs from the point ``c_k + q_k e_k``. The slide's
  *block* (its short member, which the clearances shift and tilt) is a
  ``carriage`` travelling with the joint, centre ``b_k = c_k + q_k e_k`` (the
  default: every joint of an arm is actuated), or a ``bushing`` fixed at the
  joint's origin, ``b_k = c_k`` (key ``block`` of the joint's table).

The end effector is the last frame: position ``p`` (complex, mm) and angle
``phi = sum(offsets) + sum(q_R)`` (rad).

Error model
-----------
Every joint of a serial arm is actuated. Each error source of joint ``k`` is
a small planar twist of the part of the arm beyond it; at the end effector a
rotation ``tau`` about a point ``c`` gives ``dphi = tau``, ``dp = tau E (p - c)``
(``E z = 1j z``) and a translation ``delta`` gives ``dp = delta``. The keys
are those of :mod:`pmaccuracy.model.sources` (half-widths, all >= 0):

==============  =================================================  ===========================
key             displacement of the part beyond joint ``k``          set at the end effector
==============  =================================================  ===========================
``radial``      translation ``|delta| <= eps`` (joint play)          disk of radius ``eps``
``position``    tolerance: the joint's centre moved, ``|delta|<=t``  disk of radius ``t``
``actuator``    ``|dq| <= eps``: R: rotation about ``c_k`` (rad);     segment
                P: translation ``dq e_k`` (mm)
``angular``     P: block tilt ``|tau| <= eps`` about ``b_k`` (rad)     segment
``direction``   tolerance: joint turned about ``c_k``, ``|tau|<=t``   segment
``length``      tolerance: link ``k`` longer by ``|dl| <= t``:        segment
                translation ``dl d_k`` along the link
``lateral``     P guide play: shift ``sigma`` along ``E e_k`` and     parallelogram (two segments)
                tilt ``tau`` about the block's ``b_k`` inside the
                rhombus ``|L tau +- 2 sigma| <= 2 eps`` (``L`` =
                ``block_length``)
==============  =================================================  ===========================

The rhombus is the convex hull of ``(+-eps, 0)`` and ``(0, +-2 eps / L)`` in
``(sigma, tau)``, i.e. the Minkowski sum of the segments ``+-(u + v) / 2`` and
``+-(u - v) / 2`` with ``u = (eps, 0)``, ``v = (0, 2 eps / L)``.

The sources are independent, so the reachable first-order end-effector
errors ``(dx, dy, dphi)`` are the Minkowski sum ``Z + D(R)`` of a zonotope
``Z = {G^T a : a in [-1, 1]^m}`` (segment generators ``G (..., m, 3)``) and a
disk of radius ``R = sum(radial + position)`` in the ``(dx, dy)`` plane:

* ``dx_max = sum_s |G_sx| + R``, ``dy_max = sum_s |G_sy| + R``,
  ``dphi_max = sum_s |G_sphi|`` (support functions);
* ``dp_max = max_{z in Z} |z_xy| + R``, attained at a vertex of the planar
  zonotope of the generators ``h_s = G_sx + i G_sy``. With every ``h_s``
  turned into the half-plane ``arg h in [0, pi)`` and sorted by angle, the
  vertices are ``v_j = 2 sum_{s <= j} h_s - sum_s h_s`` (``j = 0 .. m``) and
  their negatives (:func:`zonotope_max_norm`, ``O(m log m)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

from . import _tomlio, plausibility
from ..errors import ClearanceError, ConfigError, GeometryError, OutsideJointLimitsError, PoseError
from .legs import check_block
from .plausibility import check_orientations
from ..numerics.screws import expi
from .sources import DEFAULT_BLOCK_LENGTH, FIRST_ORDER_ONLY, KEYS, JointErrors

#: Value of ``architecture`` in a serial arm's robot file.
ARCHITECTURE = "serial"
#: Keys of the top level and of one ``[[joints]]`` table of a serial robot file.
TOP_KEYS = {"architecture", "name", "description", "joints"}
JOINT_KEYS = {"type", "length", "offset_deg", "range", "name", "description", "block"}
#: Output quantities with a worst-case configuration.
QUANTITIES = ("dx", "dy", "dphi", "dp")


def _deg(angle: float) -> float:
    return _tomlio.round_trip_degrees(angle)


@dataclass(frozen=True)
class SerialJoint:
    """One joint of a serial arm (module docstring for the convention).

    kind : ``"R"`` or ``"P"``;  length : mm, link along the x-axis after the joint;
    offset : rad, turn of the frame before the joint's motion;
    range : ``(lo, hi)`` of ``q``, rad (R) or mm (P);  name, description : labels
    block : P only: ``"carriage"`` (default) or ``"bushing"`` (module docstring)
    """

    kind: str
    length: float = 0.0
    offset: float = 0.0
    range: tuple[float, float] = (-math.inf, math.inf)
    name: str = ""
    description: str = ""
    block: str | None = None

    @property
    def block_kind(self) -> str | None:
        """``"carriage"`` or ``"bushing"`` for a P joint (a carriage unless :attr:`block` says otherwise)."""
        return None if self.kind != "P" else (self.block or "carriage")

    @property
    def unit(self) -> str:
        """Unit of ``q`` on the command line and in files: ``"deg"`` (R) or ``"mm"`` (P)."""
        return "deg" if self.kind == "R" else "mm"


@dataclass(frozen=True)
class SerialArm(_tomlio.TomlPresets):
    """A planar serial arm of R and P joints, base to tip (``architecture = "serial"`` robot files).

    >>> arm = SerialArm((SerialJoint("R", 300.0), SerialJoint("R", 250.0)))
    >>> np.round(arm.forward(np.radians([90.0, -90.0])), 9).tolist()
    [250.0, 300.0, 0.0]
    """

    joints: tuple[SerialJoint, ...]
    name: str = "custom"
    description: str = ""
    KIND: ClassVar[str] = "robot"
    PRESET_FOLDER: ClassVar[str] = "robots"

    def __post_init__(self) -> None:
        if len(self.joints) == 0:
            raise GeometryError("a serial arm needs at least one joint", source=self.name, key="joints")
        for k, j in enumerate(self.joints, start=1):
            where = f"joints[{k}]"
            if j.kind not in ("R", "P"):
                raise GeometryError(f"type must be \"R\" or \"P\", got {j.kind!r}", source=self.name,
                                    key=f"{where}.type")
            for key, value in (("length", j.length), ("offset_deg", j.offset)):
                if not math.isfinite(value):
                    raise GeometryError(f"must be finite, got {value}", source=self.name, key=f"{where}.{key}")
            if j.length < 0:
                raise GeometryError(f"must not be negative, got {j.length}", source=self.name,
                                    key=f"{where}.length")
            check_block(j.kind, j.block, source=self.name, key=f"{where}.block")
            lo, hi = j.range
            if math.isnan(lo) or math.isnan(hi) or not lo < hi:
                raise GeometryError(f"empty range [{lo}, {hi}] (min must be below max)", source=self.name,
                                    key=f"{where}.range")

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joints)

    @property
    def kinds(self) -> str:
        """The joint types base to tip, e.g. ``"RRR"``."""
        return "".join(j.kind for j in self.joints)

    @property
    def architecture(self) -> str:
        return ARCHITECTURE

    def label(self, k: int) -> str:
        """``joint k (name)`` for messages, ``k`` 1-based."""
        name = self.joints[k - 1].name
        return f"joint {k} ({name})" if name else f"joint {k}"

    # ------------------------------------------------------------------ files
    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "SerialArm":
        """Build from a parsed robot file (``architecture = "serial"``, ``[[joints]]``; degrees in the file)."""
        arch = data.get("architecture")
        if arch != ARCHITECTURE:
            raise ConfigError(f"a serial arm's file needs architecture = \"serial\", got {arch!r}", source=source,
                              key="architecture")
        _tomlio.reject_unknown(data, TOP_KEYS, source=source, where="")
        tables = data.get("joints")
        if tables is None:
            raise GeometryError("missing [[joints]] tables (at least one, base to tip)", source=source, key="joints")
        if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
            raise GeometryError("must be an array of tables [[joints]]", source=source, key="joints")
        if not tables:
            raise GeometryError("a serial arm needs at least one [[joints]] table", source=source, key="joints")
        joints = []
        for k, t in enumerate(tables, start=1):
            where = f"joints[{k}]"
            _tomlio.reject_unknown(t, JOINT_KEYS, source=source, where=where)
            kind = t.get("type")
            if kind not in ("R", "P"):
                raise GeometryError(f"must be \"R\" or \"P\", got {kind!r}" if "type" in t else "missing (\"R\" or "
                                    "\"P\")", source=source, key=f"{where}.type")
            length = _tomlio.number(t, "length", source=source, where=where, default=0.0, nonnegative=True)
            offset = math.radians(_tomlio.number(t, "offset_deg", source=source, where=where, default=0.0))
            lo, hi = _tomlio.interval(t, "range", source=source, where=where)
            if kind == "R":
                lo, hi = math.radians(lo), math.radians(hi)
            texts = {}
            for key in ("name", "description"):
                value = t.get(key, "")
                if not isinstance(value, str):
                    raise ConfigError("must be a string", source=source, key=f"{where}.{key}")
                texts[key] = value
            block = t.get("block")
            check_block(kind, block, source=source, key=f"{where}.block")
            joints.append(SerialJoint(kind, length, offset, (lo, hi), **texts, block=block))
        name = data.get("name", source[:-len(".toml")].rsplit("/", 1)[-1] if source.endswith(".toml") else source)
        description = data.get("description", "")
        for key, value in (("name", name), ("description", description)):
            if not isinstance(value, str):
                raise ConfigError("must be a string", source=source, key=key)
        return cls(joints=tuple(joints), name=name, description=description)

    def to_dict(self) -> dict[str, Any]:
        """The TOML table (degrees for angles and R ranges)."""
        out: dict[str, Any] = {"architecture": ARCHITECTURE, "name": self.name}
        if self.description:
            out["description"] = self.description
        tables = []
        for j in self.joints:
            lo, hi = j.range
            t: dict[str, Any] = {"type": j.kind, "length": j.length, "offset_deg": _deg(j.offset),
                                 "range": [_deg(lo), _deg(hi)] if j.kind == "R" else [lo, hi]}
            if j.name:
                t["name"] = j.name
            if j.description:
                t["description"] = j.description
            if j.block is not None:
                t["block"] = j.block
            tables.append(t)
        out["joints"] = tables
        return out

    # ------------------------------------------------------------------ kinematics
    def _q(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.ndim == 0 or q.shape[-1] != self.n:
            raise PoseError(f"{self.name}: expected {self.n} joint values per configuration ({self.kinds}), "
                            f"got shape {q.shape}")
        return q

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Joint geometry at joint values ``q (..., n)`` (rad for R, mm for P), base frame.

        Returns ``centres (..., n)`` complex mm (frame origin before joint k: an R
        joint's centre, a P joint's slide origin ``c_k``), ``directions (..., n)``
        complex unit (x-axis after joint k's turn: ``exp(i a_k)``, the link's
        direction and a P joint's slide direction ``e_k``), and the end frame's
        ``angle (...)`` rad and ``origin (...)`` complex mm::

            a_k = a_{k-1} + offset_k + (q_k if R else 0),   a_0 = 0
            c_{k+1} = c_k + exp(i a_k) (length_k + (q_k if P else 0)),   c_1 = 0
        """
        q = self._q(q)
        angle = np.zeros(q.shape[:-1])
        pos = np.zeros(q.shape[:-1], dtype=complex)
        centres, dirs = [], []
        for k, j in enumerate(self.joints):
            centres.append(pos)
            angle = angle + j.offset + (q[..., k] if j.kind == "R" else 0.0)
            e = expi(angle)
            dirs.append(e)
            pos = pos + e * (j.length + (q[..., k] if j.kind == "P" else 0.0))
        return np.stack(centres, axis=-1), np.stack(dirs, axis=-1), angle, pos

    def forward(self, q: np.ndarray) -> np.ndarray:
        """End-effector poses ``(..., 3)`` [x mm, y mm, phi rad] at joint values ``q (..., n)``; phi is not wrapped."""
        _, _, angle, end = self.frames(q)
        return np.stack([end.real, end.imag, angle], axis=-1)

    def joints_from_cli(self, values: np.ndarray) -> np.ndarray:
        """Joint values in file units (deg for R, mm for P), ``(..., n)``, to rad / mm."""
        values = self._q(values)
        scale = np.array([math.pi / 180.0 if j.kind == "R" else 1.0 for j in self.joints])
        return values * scale

    def joints_to_cli(self, q: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`joints_from_cli`."""
        q = self._q(q)
        scale = np.array([180.0 / math.pi if j.kind == "R" else 1.0 for j in self.joints])
        return q * scale

    def check_joints(self, q: np.ndarray, *, allow_outside: bool = False) -> np.ndarray:
        """``q (..., n)`` as floats; raises :class:`PoseError` for non-finite values and, unless
        ``allow_outside``, :class:`OutsideJointLimitsError` naming the first configuration and joint out of range."""
        q = self._q(q)
        flat = q.reshape(-1, self.n)
        bad = ~np.isfinite(flat)
        if bad.any():
            i, k = np.argwhere(bad)[0]
            raise PoseError(f"configuration {i + 1}: {self.label(k + 1)} is not finite")
        if not allow_outside:
            lo = np.array([j.range[0] for j in self.joints])
            hi = np.array([j.range[1] for j in self.joints])
            out = (flat < lo) | (flat > hi)
            if out.any():
                i, k = np.argwhere(out)[0]
                shown = self.joints_to_cli(flat[i])[k]
                lo_c, hi_c = self.joints_to_cli(lo)[k], self.joints_to_cli(hi)[k]
                unit = self.joints[k].unit
                raise OutsideJointLimitsError(
                    f"configuration {i + 1}: {self.label(k + 1)} = {shown:.6g} {unit} is outside its range "
                    f"[{lo_c:.6g}, {hi_c:.6g}] {unit} of {self.name}")
        return q


def is_serial_spec(spec) -> bool:
    """True when ``spec`` (a :class:`SerialArm`, a robot preset name or a TOML file) is a serial arm.

    Unreadable specs give False, so that the parallel-robot loader reports them as before.
    """
    if isinstance(spec, SerialArm):
        return True
    if not isinstance(spec, (str, bytes)) and not hasattr(spec, "__fspath__"):
        return False
    try:
        data, _ = _tomlio.read_spec(spec, kind="robot", folder="robots")
    except ConfigError:
        return False
    return data.get("architecture") == ARCHITECTURE


# ====================================================================== error sources

@dataclass(frozen=True)
class SerialErrorSources:
    """Half-widths of the error sources of each joint of a serial arm, base to tip (module docstring).

    File format: a clearance file with exactly one ``[[legs]]`` entry whose
    ``joints`` list one table per joint (keys of :data:`pmaccuracy.model.sources.KEYS`)::

        name = "arm_typical"
        [[legs]]
        joints = [{ radial = 0.005, actuator = 0.0003 }, { actuator = 0.0003 }, { actuator = 0.0005 }]
    """

    joints: tuple[JointErrors, ...]
    name: str = "custom"

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>", arm: SerialArm | None = None
                  ) -> "SerialErrorSources":
        """Parse the file format above; with ``arm``, also check each key against its joint's type (names the key)."""
        _tomlio.reject_unknown(data, {"name", "description", "legs"}, source=source, where="")
        legs = data.get("legs")
        if legs is None:
            raise ClearanceError("missing [[legs]]: a serial arm's clearance file has one [[legs]] entry listing "
                                 "its joints base to tip", source=source, key="legs")
        if not isinstance(legs, list) or not all(isinstance(leg, dict) for leg in legs):
            raise ClearanceError("must be an array of tables [[legs]]", source=source, key="legs")
        if len(legs) != 1:
            raise ClearanceError(f"a serial arm's clearance file has exactly one [[legs]] entry, found {len(legs)}",
                                 source=source, key="legs")
        where = "legs[1]"
        _tomlio.reject_unknown(legs[0], {"joints"}, source=source, where=where)
        tables = legs[0].get("joints")
        if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
            raise ClearanceError("must be a list of tables {key = value, ...}, one per joint base to tip",
                                 source=source, key=f"{where}.joints")
        if arm is not None and len(tables) != arm.n:
            raise ClearanceError(f"{arm.name} has {arm.n} joints ({arm.kinds}), this list has {len(tables)}",
                                 source=source, key=f"{where}.joints")
        parsed = []
        for k, t in enumerate(tables, start=1):
            jw = f"{where}.joints[{k}]"
            _tomlio.reject_unknown(t, set(KEYS), source=source, where=jw)
            values = {key: _tomlio.number(t, key, source=source, where=jw, nonnegative=True) for key in t}
            if "block_length" in values and values["block_length"] <= 0:
                raise ClearanceError(f"must be positive, got {values['block_length']}", source=source,
                                     key=f"{jw}.block_length")
            if arm is not None:
                for key in t:
                    _check_key(arm, k, key, source)
            parsed.append(JointErrors(**values))
        name = data.get("name", source)
        if not isinstance(name, str):
            raise ConfigError("must be a string", source=source, key="name")
        return cls(joints=tuple(parsed), name=name)

    def to_dict(self) -> dict[str, Any]:
        """The TOML table (only non-default keys)."""
        default = JointErrors()
        joints = [{f.name: getattr(j, f.name) for f in fields(j) if getattr(j, f.name) != getattr(default, f.name)}
                  for j in self.joints]
        return {"name": self.name, "legs": [{"joints": joints}]}

    def check(self, arm: SerialArm) -> "SerialErrorSources":
        """Refuse a joint count other than the arm's, negative or non-finite values, and keys that do not fit the
        joint type (``angular``, ``lateral`` on an R joint), naming ``legs[1].joints[k].key``."""
        if len(self.joints) != arm.n:
            raise ClearanceError(f"{arm.name} has {arm.n} joints ({arm.kinds}), these sources list "
                                 f"{len(self.joints)}", source=self.name, key="legs[1].joints")
        for k, errs in enumerate(self.joints, start=1):
            for f in fields(errs):
                value = getattr(errs, f.name)
                key = f"legs[1].joints[{k}].{f.name}"
                if not math.isfinite(value) or value < 0 or (f.name == "block_length" and value == 0):
                    raise ClearanceError(f"must be finite and {'> 0' if f.name == 'block_length' else '>= 0'}, "
                                         f"got {value}", source=self.name, key=key)
                default = DEFAULT_BLOCK_LENGTH if f.name == "block_length" else 0.0
                if value != default:
                    _check_key(arm, k, f.name, self.name)
        return self


def _check_key(arm: SerialArm, k: int, key: str, source: str) -> None:
    """Raise unless source ``key`` applies to joint ``k`` (1-based) of ``arm`` (every joint is actuated)."""
    if key in FIRST_ORDER_ONLY:
        raise ClearanceError(f"{key} (a leg's polar tolerance) applies to the legs of parallel robots; give a "
                             "serial arm's tolerances as position, direction or length", source=source,
                             key=f"legs[1].joints[{k}].{key}")
    allowed = KEYS[key]
    kind = arm.joints[k - 1].kind
    if allowed == "A" or kind in allowed:
        return
    raise ClearanceError(f"{key} applies to prismatic joints only; {arm.label(k)} of {arm.name} is an R joint",
                         source=source, key=f"legs[1].joints[{k}].{key}")


def load_serial_sources(spec, arm: SerialArm) -> SerialErrorSources:
    """Error sources for ``arm`` from a clearance preset name, a TOML file or a :class:`SerialErrorSources`."""
    if isinstance(spec, SerialErrorSources):
        return spec.check(arm)
    if isinstance(spec, str) and spec == "none":   # the preset of no clearance, for every architecture
        return SerialErrorSources(joints=(JointErrors(),) * arm.n, name="none")
    data, source = _tomlio.read_spec(spec, kind="clearance", folder="clearances")
    legs = data.get("legs")
    if isinstance(legs, list) and legs and not any(isinstance(leg, dict) and "joints" in leg for leg in legs):
        raise ClearanceError(
            "this file uses the 3-PPR clearance format (bearing_angle, guide_lateral, revolute_radial per leg), "
            f"which does not fit the serial arm {arm.name}: give one [[legs]] entry listing its {arm.n} joints, "
            "e.g. joints = [{radial = 0.005, actuator = 0.0003}, ...] (preset arm_typical)",
            source=source, key="legs")
    sources = SerialErrorSources.from_dict(data, source=source, arm=arm)
    plausibility.warn(plausibility.actuator_messages(
        ((f"legs[1].joints[{k}].actuator", errs.actuator, joint.kind == "R")
         for k, (joint, errs) in enumerate(zip(arm.joints, sources.joints), start=1)), source))
    return sources


# ====================================================================== exact bounds

@dataclass(frozen=True)
class ErrorLayout:
    """Where each error source sits among the generators (configuration-independent).

    segments : per source key ``"joints[k].<key>"`` with segments, ``(start, stop, weights (stop - start, d))``:
        the source's value is ``sum_s a_s weights[s]`` for coefficients ``a_s in [-1, 1]`` of its segments
        (``d = 1``: mm or rad; ``d = 2``: the guide's ``(sigma mm, tau rad)``)
    disks : per source key with a disk, its radius (mm); its value is a translation ``(dx, dy)`` mm
    """

    segments: dict[str, tuple[int, int, np.ndarray]] = field(default_factory=dict)
    disks: dict[str, float] = field(default_factory=dict)

    @property
    def disk_radius(self) -> float:
        """``R``: the sum of the disks' radii (mm)."""
        return float(sum(self.disks.values()))


def error_generators(arm: SerialArm, sources: SerialErrorSources, q: np.ndarray
                     ) -> tuple[np.ndarray, ErrorLayout]:
    """Segment generators ``G (..., m, 3)`` [dx mm, dy mm, dphi rad] of the first-order end-effector error set.

    At joint values ``q (..., n)`` with centres ``c_k``, directions ``d_k``
    (:meth:`SerialArm.frames`) and end position ``p``, a unit rotation about
    ``c`` gives ``rot(c) = (Re E(p - c), Im E(p - c), 1)`` and a unit
    translation along ``e`` gives ``tr(e) = (Re e, Im e, 0)``; the generators
    (module docstring) are ``eps * rot(c_k)`` (R actuator, direction), ``eps * rot(b_k)`` (angular),
    ``eps * tr(d_k)`` (P actuator, length) and, for the guide,
    ``(eps tr(E d_k) +- (2 eps / L) rot(b_k)) / 2``, with the block's centre ``b_k = c_k + q_k d_k``
    (carriage) or ``c_k`` (bushing).
    The disks (radial, position) are in the returned :class:`ErrorLayout`.
    """
    q = arm._q(q)
    centres, dirs, _, end = arm.frames(q)

    def rot(c):
        arm_ = 1j * (end - c)
        return np.stack([arm_.real, arm_.imag, np.ones(arm_.shape)], axis=-1)

    def tr(e):
        return np.stack([e.real, e.imag, np.zeros(e.shape)], axis=-1)

    gens: list[np.ndarray] = []
    layout = ErrorLayout()

    def add(key, columns, weights):
        start = len(gens)
        gens.extend(columns)
        layout.segments[key] = (start, len(gens), np.asarray(weights, dtype=float).reshape(len(columns), -1))

    for k, (joint, e) in enumerate(zip(arm.joints, sources.joints)):
        c, d = centres[..., k], dirs[..., k]
        name = f"joints[{k + 1}]"
        for key in ("radial", "position"):
            if getattr(e, key):
                layout.disks[f"{name}.{key}"] = getattr(e, key)
        if e.actuator:
            add(f"{name}.actuator", [e.actuator * (rot(c) if joint.kind == "R" else tr(d))], [e.actuator])
        block = c + q[..., k] * d if joint.block_kind == "carriage" else c   # the P block's centre (R: unused)
        for key, centre in (("angular", block), ("direction", c)):
            if getattr(e, key):
                add(f"{name}.{key}", [getattr(e, key) * rot(centre)], [getattr(e, key)])
        if e.length:
            add(f"{name}.length", [e.length * tr(d)], [e.length])
        if e.lateral:
            u = e.lateral * tr(1j * d)
            v = (2 * e.lateral / e.block_length) * rot(block)
            half = [e.lateral / 2, e.lateral / e.block_length]
            add(f"{name}.lateral", [(u + v) / 2, (u - v) / 2], [half, [half[0], -half[1]]])
    shape = q.shape[:-1] + (len(gens), 3)
    G = np.stack(gens, axis=-2) if gens else np.zeros(shape)
    return G, layout


def zonotope_max_norm(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``max |z|`` over the planar zonotope ``{sum_s a_s h_s : a in [-1, 1]^m}`` and the signs attaining it.

    ``h (..., m)`` complex generators (mm). Each ``h_s`` is turned into the
    half-plane ``arg in [0, pi)`` (sign ``f_s``) and sorted by angle; the
    vertices are ``v_j = 2 S_j - H`` with ``S_j`` the sum of the first ``j``
    sorted generators (``j = 0 .. m``) and ``H`` the sum of all, and the
    largest ``|v_j|`` is the answer (a convex function peaks at a vertex; the
    other ``m`` vertices are the ``-v_j``). Returns ``(max (...), a (..., m))``
    with ``a_s = +-1`` such that ``|sum_s a_s h_s|`` is the maximum.

    >>> float(zonotope_max_norm(np.array([1 + 0j, 1j]))[0]) == math.sqrt(2)
    True
    """
    h = np.asarray(h, dtype=complex)
    flip = np.where((h.imag < 0) | ((h.imag == 0) & (h.real < 0)), -1.0, 1.0)
    hp = h * flip
    order = np.argsort(np.angle(hp), axis=-1, kind="stable")
    hs = np.take_along_axis(hp, order, axis=-1)
    total = hs.sum(axis=-1)
    partial = np.concatenate([np.zeros(h.shape[:-1] + (1,), dtype=complex), np.cumsum(hs, axis=-1)], axis=-1)
    vertices = 2 * partial - total[..., None]
    norms = np.abs(vertices)
    j = np.argmax(norms, axis=-1)
    best = np.take_along_axis(norms, j[..., None], axis=-1)[..., 0]
    m = h.shape[-1]
    sorted_signs = np.where(np.arange(m) < j[..., None], 1.0, -1.0)
    signs = np.empty(h.shape)
    np.put_along_axis(signs, order, sorted_signs, axis=-1)
    return best, signs * flip


@dataclass(frozen=True)
class SerialErrorBounds:
    """Exact first-order worst-case end-effector errors of a serial arm at joint configurations.

    Attributes (leading shape ``(...)`` of the configurations)
    ----------------------------------------------------------
    joints : ``(..., n)`` rad (R) / mm (P);  poses : ``(..., 3)`` [mm, mm, rad]
    dx_max, dy_max, dp_max : ``(...)`` mm;  dphi_max : ``(...)`` rad
    generators : ``(..., m, 3)`` segment generators;  layout : :class:`ErrorLayout`
    worst : with ``details=True``, per quantity (``dx, dy, dphi, dp``) the value of
        each source at the maximum (``+dx_max`` etc.): ``"joints[k].<key>"`` ->
        ``(...)`` mm or rad, ``(..., 2)`` ``(sigma mm, tau rad)`` for ``lateral``,
        ``(..., 2)`` ``(dx, dy)`` mm for disks (0 for dphi, which disks do not change); a segment source
        that does not change the quantity sits at ``+`` its half-width (any value attains the maximum)
    """

    joints: np.ndarray
    poses: np.ndarray
    dx_max: np.ndarray
    dy_max: np.ndarray
    dphi_max: np.ndarray
    dp_max: np.ndarray
    generators: np.ndarray
    layout: ErrorLayout
    worst: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def dphi_max_deg(self) -> np.ndarray:
        """``dphi_max`` in degrees."""
        return np.degrees(self.dphi_max)

    def columns(self) -> dict[str, np.ndarray]:
        """The ``bounds`` output columns, 1-D: ``x, y, phi_deg, dx_max, dy_max, dphi_max_deg, dp_max``."""
        poses = self.poses.reshape(-1, 3)
        return {"x": poses[:, 0], "y": poses[:, 1], "phi_deg": np.degrees(poses[:, 2]),
                "dx_max": self.dx_max.reshape(-1), "dy_max": self.dy_max.reshape(-1),
                "dphi_max_deg": self.dphi_max_deg.reshape(-1), "dp_max": self.dp_max.reshape(-1)}


def _source_values(layout: ErrorLayout, coeffs: np.ndarray, disk_dir: np.ndarray | None) -> dict[str, np.ndarray]:
    """Each source's value for segment coefficients ``coeffs (..., m)`` and disk translations along the unit
    complex ``disk_dir (...)`` (None: no translation)."""
    out = {}
    for key, (start, stop, weights) in layout.segments.items():
        value = coeffs[..., start:stop] @ weights
        out[key] = value[..., 0] if weights.shape[1] == 1 else value
    for key, radius in layout.disks.items():
        if disk_dir is None:
            out[key] = np.zeros(coeffs.shape[:-1] + (2,))
        else:
            out[key] = radius * np.stack([disk_dir.real, disk_dir.imag], axis=-1)
    return out


def max_serial_errors(arm: SerialArm, sources, q: np.ndarray, *, allow_outside: bool = False,
                      details: bool = False) -> SerialErrorBounds:
    """Exact worst-case ``dx, dy, dphi, |dp|`` of the end effector at joint values ``q (..., n)`` (rad / mm).

    With the segment generators ``G (..., m, 3)`` (:func:`error_generators`)
    and the total disk radius ``R``::

        dx_max = sum_s |G_sx| + R      dy_max = sum_s |G_sy| + R      dphi_max = sum_s |G_sphi|
        dp_max = max_{a in [-1, 1]^m} |sum_s a_s (G_sx + i G_sy)| + R      (zonotope_max_norm)

    ``sources`` is a :class:`SerialErrorSources` or anything
    :func:`load_serial_sources` takes. Joint values outside the ranges raise
    :class:`~pmaccuracy.errors.OutsideJointLimitsError` unless ``allow_outside``.
    ``details=True`` adds the worst-case source values (:class:`SerialErrorBounds`).
    """
    try:   # revolute joint values in rad: degrees typed in warn (malformed q: check_joints names it)
        revolute = np.asarray(q, dtype=float)[..., [k == "R" for k in arm.kinds]]
    except (TypeError, ValueError, IndexError):
        revolute = None
    if revolute is not None:
        check_orientations(revolute, "q (revolute joints)", "revolute joint values")
    sources = load_serial_sources(sources, arm)
    q = arm.check_joints(q, allow_outside=allow_outside)
    G, layout = error_generators(arm, sources, q)
    R = layout.disk_radius
    absG = np.abs(G)
    dx, dy, dphi = absG[..., 0].sum(-1) + R, absG[..., 1].sum(-1) + R, absG[..., 2].sum(-1)
    h = G[..., 0] + 1j * G[..., 1]
    zmax, dp_signs = zonotope_max_norm(h)
    worst: dict[str, dict[str, np.ndarray]] = {}
    if details:
        ones = np.ones(q.shape[:-1], dtype=complex)
        vertex = np.sum(dp_signs * h, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            towards = np.where(np.abs(vertex) > 0, vertex / np.abs(vertex), 1.0 + 0j)
        sign = lambda a: np.where(a >= 0, 1.0, -1.0)  # noqa: E731
        worst = {"dx": _source_values(layout, sign(G[..., 0]), ones),
                 "dy": _source_values(layout, sign(G[..., 1]), 1j * ones),
                 "dphi": _source_values(layout, sign(G[..., 2]), None),
                 "dp": _source_values(layout, dp_signs, towards)}
    return SerialErrorBounds(joints=q, poses=arm.forward(q), dx_max=dx, dy_max=dy, dphi_max=dphi,
                             dp_max=zmax + R, generators=G, layout=layout, worst=worst)
