r"""Clearances under load for planar serial arms: statics and the end-effector error a known wrench produces.

The serial counterpart of :mod:`pmaccuracy.accuracy.loads` (issue 24, deliverable 1). The
:class:`~pmaccuracy.accuracy.loads.Load` acts on the end link: ``(f_x, f_y)`` N and ``m`` N mm about the end
point ``p`` in the base frame, plus the end link's weight at ``com`` (end frame, mm).

**Statics** (massless links). The part of the arm beyond joint ``k`` is in equilibrium
under the external wrench and what the proximal part exerts on it through joint ``k``: the force
``F_k = -f`` (the same at every joint) and the moment about the joint's centre ``c_k``

.. math::

    M_k = -\left(m + (p - c_k) \times f\right) \quad \text{(N mm)}.

The actuator supplies the component the joint does not carry passively: ``tau_k = M_k`` (R, N mm,
counter-clockwise on the part beyond the joint) or ``tau_k = F_k \cdot e_k`` (P, N along the slide ``e_k``).
This is virtual work with the arm's Jacobian ``J`` (columns: ``rot(c_k)`` or ``tr(e_k)``,
:func:`pmaccuracy.model.serial.error_generators`): ``tau . dq + W . dX = 0`` for every ``dq``, i.e.

.. math::

    \tau = -J^T W .

A P joint's block carries the normal force ``N_k = F_k \cdot E e_k`` and the moment about its centre
``M_k(b_k) = -(m + (p - b_k) \times f)``, i.e. the two end contact forces ``N / 2 -+ M / L`` of a block of
length ``L``.

**Loaded error.** Each error source of joint ``k`` is a small rigid motion of the part beyond it
(:mod:`pmaccuracy.model.serial`). The clearance lets the arm yield where the load does work: the reached
error maximizes ``W . dX`` over the error set. To first order the set is the zonotope
``{G^T a : a in [-1, 1]^m}`` plus disks (``radial``, ``position``) of radii ``r_j`` in ``(dx, dy)``, so

.. math::

    a_s = \operatorname{sign}(G_s \cdot W), \qquad
    \delta X_{\text{loaded}} = G^T a + \Big(\sum_j r_j\Big) \frac{(f, 0)}{|f|},

its support point in the direction ``W`` (an R joint's actuator backlash against its torque, a pin against
the bore opposite the force, a P block on the rhombus vertex that its two end contact forces select: the
guide's two segments are ``+-`` its end contacts). A segment is **unloaded** when its generalized reaction
``|G_s . W| / eps_s`` is at most ``threshold`` (N for the translations: P actuator, length, the guide's end
contact forces; N mm for the rotations about a point: R actuator, direction, angular); a disk when
``|f| <= threshold`` N. Unloaded sources are left at 0 and give the ``spread``: the half-width of the range
they still span (``sum |G_s|`` over unloaded segments, ``r`` in ``dx`` and ``dy`` for unloaded disks).

**Exact loaded pose.** With those source values every source is applied as an exact rigid motion of the
end pose (rotation by ``tau`` about the nominal point ``c_k`` or ``b_k``:
``p -> c + e^{i tau} (p - c)``, ``phi -> phi + tau``; translation ``p -> p + delta``), composed

.. math::

    X = D_1(D_2(\cdots D_n(X_{\text{nom}})))

(joint ``n``'s motions first). Within joint ``k`` the order is, first applied first: ``length`` (along
``d_k``), ``lateral`` (tilt ``tau`` about ``b_k``, then shift ``sigma`` along ``E d_k``), ``angular`` (about
``b_k``), ``actuator`` (R: about ``c_k``; P: along ``d_k``), ``direction`` (about ``c_k``), ``position``,
``radial`` (translations). Composing motions defined on the nominal geometry in this order is the same as
perturbing each joint in its own (displaced) link frame: e.g. actuator, direction and length errors give
exactly :meth:`~pmaccuracy.model.serial.SerialArm.forward` of the arm with ``q_k``, ``offset_k`` and
``length_k`` changed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._display import html_table, summary, value_range
from ..errors import ConfigError
from ..model.plausibility import check_orientations
from ..model.serial import SerialArm, error_generators, load_serial_sources
from ..numerics.screws import cross, dot, expi
from .loads import DEFAULT_THRESHOLD_N, Load

#: Order in which one joint's sources are applied to the part beyond it (first applied first).
SOURCE_ORDER = ("length", "lateral", "angular", "actuator", "direction", "position", "radial")


def _arm(arm) -> SerialArm:
    if isinstance(arm, SerialArm):
        return arm
    if isinstance(arm, str) or hasattr(arm, "__fspath__"):
        return SerialArm.load(arm)
    raise ConfigError(f"expected a SerialArm, a preset name or a robot file, got {type(arm).__name__}", key="arm")


def _revolute(arm: SerialArm, q):
    """The revolute joint values of ``q`` (for the degrees check; none when malformed: check_joints names it)."""
    try:
        return np.asarray(q, dtype=float)[..., [k == "R" for k in arm.kinds]]
    except (TypeError, ValueError, IndexError):
        return []


def _checked(arm: SerialArm, q, load, allow_outside: bool) -> tuple[SerialArm, np.ndarray]:
    q = arm.check_joints(q, allow_outside=allow_outside)
    if not isinstance(load, Load):
        raise ConfigError(f"expected a Load, got {type(load).__name__}", key="load")
    return arm, q


@dataclass(frozen=True)
class SerialStatics:
    """Joint reactions and actuator efforts of a serial arm under a load (:func:`serial_statics`), arrays with
    the configurations' leading shape ``(...)``, ``n`` joints.

    Attributes
    ----------
    joints : ``(..., n)`` rad / mm;  poses : ``(..., 3)`` [mm, mm, rad] end poses
    wrench : ``(..., 3)`` [fx N, fy N, m N mm about the end point]: the external load on the end link
    force : ``(..., n)`` complex N: force the proximal part exerts on the part beyond joint ``k`` (``-f``)
    moment : ``(..., n)`` N mm: its moment about the joint's centre ``c_k``
    actuator : ``(..., n)``: ``tau_k`` (R: N mm, P: N), ``tau = -J^T W``
    normal : ``(..., n)`` N: a P block's force normal to its rail ``F_k . E e_k`` (0 for R joints)
    block_moment : ``(..., n)`` N mm: a P block's moment about its centre ``b_k`` (0 for R joints)
    """

    joints: np.ndarray
    poses: np.ndarray
    wrench: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    actuator: np.ndarray
    normal: np.ndarray
    block_moment: np.ndarray

    def contact_forces(self, block_length) -> np.ndarray:
        """``(..., n, 2)`` N: the two end contact forces ``N / 2 -+ M / L`` of each P block of length ``L`` (mm;
        a scalar or ``(n,)``), normal to the rail; zero for R joints."""
        L = np.asarray(block_length, dtype=float)
        return np.stack([self.normal / 2 - self.block_moment / L, self.normal / 2 + self.block_moment / L], axis=-1)

    def __repr__(self) -> str:
        return summary("SerialStatics", int(np.prod(self.poses.shape[:-1])), [
            f"joint force {value_range(np.abs(self.force), 'N')}",
            f"actuators {value_range(np.abs(self.actuator), 'N or N mm')}"])


def serial_statics(arm: SerialArm | str, q, load: Load, *, allow_outside: bool = False) -> SerialStatics:
    """Joint reactions and actuator efforts of ``arm`` at joint values ``q (..., n)`` (rad for R, mm for P)
    under ``load`` on the end link (module docstring: ``F_k = -f``, ``M_k = -(m + (p - c_k) x f)``,
    ``tau = -J^T W``).

    >>> arm = SerialArm.load("planar_3r_arm")
    >>> st = serial_statics(arm, [0.0, 0.0, 0.0], Load(fy=-10.0))   # 10 N down at the tip, 650 mm out
    >>> st.actuator.round(6).tolist()                               # the shoulder holds 6500 N mm
    [6500.0, 3500.0, 1000.0]
    """
    arm = _arm(arm)
    check_orientations(_revolute(arm, q), "q (revolute joints)", "revolute joint values")   # rad: degrees warn
    arm, q = _checked(arm, q, load, allow_outside)
    return _statics(arm, q, load)


def _statics(arm: SerialArm, q: np.ndarray, load: Load) -> SerialStatics:
    centres, dirs, angle, end = arm.frames(q)
    poses = np.stack([end.real, end.imag, angle], axis=-1)
    W = load.wrench(poses)
    f = (W[..., 0] + 1j * W[..., 1])[..., None]
    m = W[..., 2][..., None]
    force = np.broadcast_to(-f, centres.shape).copy()
    moment = -(m + cross(end[..., None] - centres, f))
    is_r = np.array([j.kind == "R" for j in arm.joints])
    actuator = np.where(is_r, moment, dot(force, dirs))
    blocks = _block_centres(arm, q, centres, dirs)
    normal = np.where(is_r, 0.0, dot(force, 1j * dirs))
    block_moment = np.where(is_r, 0.0, -(m + cross(end[..., None] - blocks, f)))
    z = 0.0     # + 0.0 turns the -0.0 of a zero load into 0.0 for display
    return SerialStatics(joints=q, poses=poses, wrench=W, force=force + z, moment=moment + z, actuator=actuator + z,
                         normal=normal + z, block_moment=block_moment + z)


def _block_centres(arm: SerialArm, q: np.ndarray, centres: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """``b_k (..., n)`` complex mm: a carriage's centre ``c_k + q_k e_k``, a bushing's ``c_k`` (R: ``c_k``)."""
    carriage = np.array([j.block_kind == "carriage" for j in arm.joints])
    return np.where(carriage, centres + q * dirs, centres)


@dataclass(frozen=True)
class SerialLoadedError:
    """The end-effector error of a serial arm under a load (:func:`loaded_serial_error`), arrays with the
    configurations' leading shape ``(...)``.

    Attributes
    ----------
    statics : the :class:`SerialStatics` behind it
    first_order : ``(..., 3)`` [mm, mm, rad]: the support point ``G^T a + R f / |f|`` of the error set along W
    exact : ``(..., 3)`` [mm, mm, rad]: the exact rigid-motion composition with the same source values (NaN
        without ``exact``)
    coefficients : ``(..., m)``: ``a_s`` of the segments (0 where unloaded)
    unloaded : ``(..., m)`` bool per segment;  disk_unloaded : ``(...)`` bool (``|f| <= threshold``)
    spread : ``(..., 3)`` [mm, mm, rad]: half-width of the range the unloaded sources still span
    values : per source key ``"joints[k].<key>"`` the value the load drives it to (mm or rad; ``lateral``:
        ``(..., 2)`` ``(sigma mm, tau rad)``; disks: ``(..., 2)`` ``(dx, dy)`` mm; 0 where unloaded)
    segment_keys : ``(m,)`` the source key of each segment;  disk_keys : the disks' source keys
    units : per joint the actuator effort's unit, ``"Nmm"`` (R) or ``"N"`` (P)
    """

    statics: SerialStatics
    first_order: np.ndarray
    exact: np.ndarray
    coefficients: np.ndarray
    unloaded: np.ndarray
    disk_unloaded: np.ndarray
    spread: np.ndarray
    values: dict
    segment_keys: tuple
    disk_keys: tuple
    units: tuple

    def unloaded_sources(self) -> list[str]:
        """Per configuration (flattened) the unloaded source keys joined by ``,`` (``-``: none)."""
        un = self.unloaded.reshape(-1, self.unloaded.shape[-1])
        dk = self.disk_unloaded.reshape(-1)
        names, disks = self.segment_keys, self.disk_keys
        out = []
        for i in range(un.shape[0]):
            keys = list(dict.fromkeys(names[s] for s in range(un.shape[1]) if un[i, s]))
            keys += list(disks) if dk[i] else []
            out.append(",".join(keys) or "-")
        return out

    def records(self) -> list[dict]:
        """One dict per configuration (mm, deg, N): the columns of ``pmaccuracy load`` with ``tau{k}_N`` or
        ``tau{k}_Nmm`` (the actuator efforts) in place of the legs' intensities."""
        poses = self.statics.poses.reshape(-1, 3)
        fo = self.first_order.reshape(-1, 3)
        ex = self.exact.reshape(-1, 3)
        tau = self.statics.actuator.reshape(-1, self.statics.actuator.shape[-1])
        sp = self.spread.reshape(-1, 3)
        keys = self.unloaded_sources()
        out = []
        for k in range(poses.shape[0]):
            out.append({"x": float(poses[k, 0]), "y": float(poses[k, 1]), "phi_deg": math.degrees(poses[k, 2]),
                        "dx": float(fo[k, 0]), "dy": float(fo[k, 1]), "dphi_deg": math.degrees(fo[k, 2]),
                        "dx_exact": float(ex[k, 0]), "dy_exact": float(ex[k, 1]),
                        "dphi_deg_exact": math.degrees(ex[k, 2]),
                        **{f"tau{j + 1}_{u}": float(tau[k, j]) for j, u in enumerate(self.units)},
                        "unloaded_sources": keys[k],
                        "dx_spread": float(sp[k, 0]), "dy_spread": float(sp[k, 1]),
                        "dphi_deg_spread": math.degrees(sp[k, 2])})
        return out

    def __repr__(self) -> str:
        return summary("SerialLoadedError", int(np.prod(self.first_order.shape[:-1])), [
            f"dx {value_range(self.first_order[..., 0], 'mm')}", f"dy {value_range(self.first_order[..., 1], 'mm')}",
            f"dphi {value_range(np.degrees(self.first_order[..., 2]), 'deg')}",
            f"{int(np.sum(self.unloaded)) + int(np.sum(self.disk_unloaded)) * len(self.disk_keys)} unloaded segments "
            "or disks"])

    def _repr_html_(self) -> str:
        return html_table("Loaded end-effector error (mm, deg, N)", self.records())


def loaded_serial_error(arm: SerialArm | str, sources, q, load: Load, *, threshold: float = DEFAULT_THRESHOLD_N,
                        exact: bool = True, allow_outside: bool = False) -> SerialLoadedError:
    """The end-effector error that ``load`` produces at joint values ``q (..., n)`` (rad / mm) with every error
    source taken to the extreme of its set that the load drives it to (module docstring), first order and (with
    ``exact``) through the exact rigid-motion composition.

    Parameters
    ----------
    arm : a :class:`~pmaccuracy.model.serial.SerialArm`, preset name or file;  sources : anything
        :func:`~pmaccuracy.model.serial.load_serial_sources` takes;  load : a :class:`~pmaccuracy.accuracy.loads.Load`
    threshold : a segment source is unloaded when ``|G_s . W| / eps_s <= threshold`` (N for translations and the
        guide's end contacts, N mm for rotations), a disk when ``|f| <= threshold`` N

    >>> from pmaccuracy.model.serial import max_serial_errors
    >>> r = loaded_serial_error("planar_3r_arm", "arm_typical", [0.0, 0.5, -0.5], Load(fy=-10.0))
    >>> b = max_serial_errors(SerialArm.load("planar_3r_arm"), "arm_typical", [0.0, 0.5, -0.5])
    >>> bool(np.isclose(r.first_order[1], -b.dy_max))     # a push along -y reaches -dy_max
    True
    """
    arm = _arm(arm)
    check_orientations(_revolute(arm, q), "q (revolute joints)", "revolute joint values")   # rad: degrees warn
    arm, q = _checked(arm, q, load, allow_outside)
    src = load_serial_sources(sources, arm)
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N or N mm), got {threshold}", key="threshold")
    st = _statics(arm, q, load)
    G, layout = error_generators(arm, src, q)
    W = st.wrench
    work = np.einsum("...si,...i->...s", G, W)                # G_s . W
    m = G.shape[-2]
    scale = np.zeros(m)
    names = [""] * m
    for key, (start, stop, _) in layout.segments.items():
        joint, name = key.split(".")
        half = getattr(src.joints[int(joint[7:-1]) - 1], name)
        scale[start:stop] = half     # G_s . W / eps: a moment, a force or (lateral) an end contact force
        names[start:stop] = [key] * (stop - start)
    with np.errstate(divide="ignore", invalid="ignore"):
        unloaded = np.abs(work) / scale <= threshold if m else np.zeros(work.shape, dtype=bool)
    a = np.where(unloaded, 0.0, np.sign(work))
    f = W[..., 0] + 1j * W[..., 1]
    disk_unloaded = np.abs(f) <= threshold
    with np.errstate(divide="ignore", invalid="ignore"):
        towards = np.where(disk_unloaded, 0.0, f / np.where(disk_unloaded, 1.0, np.abs(f)))
    R = layout.disk_radius
    first = np.einsum("...s,...si->...i", a, G)
    first[..., 0] += R * towards.real
    first[..., 1] += R * towards.imag
    spread = np.einsum("...s,...si->...i", unloaded.astype(float), np.abs(G))
    spread[..., 0] += np.where(disk_unloaded, R, 0.0)
    spread[..., 1] += np.where(disk_unloaded, R, 0.0)
    values = {}
    for key, (start, stop, weights) in layout.segments.items():
        v = a[..., start:stop] @ weights
        values[key] = v[..., 0] if weights.shape[1] == 1 else v
    for key, radius in layout.disks.items():
        values[key] = radius * np.stack([towards.real, towards.imag], axis=-1)
    if exact:
        ex = displaced_serial_pose(arm, q, values) - st.poses
    else:
        ex = np.full(first.shape, np.nan)
    units = tuple("Nmm" if j.kind == "R" else "N" for j in arm.joints)
    return SerialLoadedError(statics=st, first_order=first, exact=ex, coefficients=a, unloaded=unloaded,
                             disk_unloaded=disk_unloaded, spread=spread, values=values,
                             segment_keys=tuple(names), disk_keys=tuple(layout.disks), units=units)


def displaced_serial_pose(arm: SerialArm, q: np.ndarray, values: dict) -> np.ndarray:
    """End poses ``(..., 3)`` [mm, mm, rad] of ``arm`` at ``q (..., n)`` with the error sources at ``values``
    (``"joints[k].<key>"`` -> mm or rad; ``lateral`` ``(..., 2)`` ``(sigma, tau)``; disks ``(..., 2)`` mm), each
    an exact rigid motion of the part beyond its joint composed in the module docstring's order."""
    q = arm._q(q)
    centres, dirs, angle, end = arm.frames(q)
    blocks = _block_centres(arm, q, centres, dirs)
    p, phi = end.copy(), angle.copy()

    def rotate(c, t):
        nonlocal p, phi
        p = c + expi(t) * (p - c)
        phi = phi + t

    for k in reversed(range(arm.n)):
        c, d, b = centres[..., k], dirs[..., k], blocks[..., k]
        for name in SOURCE_ORDER:
            v = values.get(f"joints[{k + 1}].{name}")
            if v is None:
                continue
            v = np.asarray(v, dtype=float)
            if name == "length" or (name == "actuator" and arm.joints[k].kind == "P"):
                p = p + v * d
            elif name == "lateral":
                rotate(b, v[..., 1])
                p = p + v[..., 0] * 1j * d
            elif name == "angular":
                rotate(b, v)
            elif name in ("actuator", "direction"):
                rotate(c, v)
            else:   # position, radial: translations (dx, dy)
                p = p + v[..., 0] + 1j * v[..., 1]
    return np.stack([p.real, p.imag, phi], axis=-1)
