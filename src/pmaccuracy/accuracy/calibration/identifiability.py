"""Identifiability of the error parameters from a set of measured poses.

The identification residual of point ``n`` (:mod:`.identify`) is the whitened inverse-kinematic residual
``e_n = W_n (q(theta; F * m_n) - offset - gain * c_n)`` (3 numbers, one per leg); its Jacobian
``J = de/dtheta`` ``(3N, P)`` is taken by central differences of the exact model. With the columns scaled
to unit length (``J_s = J D^-1``, ``D = diag(|J_j|)``: parameters of different units compared fairly) the
singular values ``s_1 >= ... >= s_L`` give

* the condition number ``s_1 / s_L``;
* the observability indices of the literature: ``O1 = (s_1 ... s_L)^(1/L) / sqrt(m)`` (Borm and Menq 1991,
  D-optimal), ``O2 = s_L / s_1`` (Driels and Pathre 1990), ``O3 = s_L`` (Nahvi and Hollerbach 1996:
  minimum singular value), ``O4 = s_L^2 / s_1`` (Nahvi and Hollerbach 1996: noise amplification);
* columns that are numerical noise (:data:`ZERO_RTOL`) are taken as zero: such a parameter "does not change
  any residual";
* the parameters the data cannot separate: columns are taken greedily in the order geometry, actuator
  gains, actuator offsets, measurement frame, and a column is *fixed at nominal* when it adds a singular
  value below ``rtol * s_1`` to those already taken. For each fixed parameter ``f`` the combination
  ``delta theta = e_f + sum_k c_k e_k`` (``J_id c = -J_f``) leaves every residual unchanged to first order:
  it is reported in words ("frame.x + 1 leg1.base.x + ...").

Practically unidentifiable parameters (``max_sigma``, :func:`.identify.identify` applies
:data:`PRACTICAL_MAX_SIGMA`): a parameter can be separable in exact arithmetic and still be determined so
weakly by the data that its estimate means nothing (a 3-PPR whose slides are turned a few degrees off
perpendicular: a leg's ``a`` then changes the residuals only through that small turn, scaled singular
values ~1e-5, above ``rtol``, and the fit wanders a metre along it). The Jacobian is the *whitened* one
(residuals divided by the stated measurement uncertainties and clearance covariance), so
``(J^T J)^-1`` is the covariance the fit would report if the data are as noisy as stated (residual scale 1:
the noise level is in it). Computed through the column-scaled SVD (:func:`inverse_normal_matrix`), it gives
each kept parameter's predicted 1-sigma; while one of them exceeds ``max_sigma`` times its
:data:`TYPICAL_CHANGE` (10 mm, 0.1 rad = 5.7 deg, a gain of 0.1 by default), the parameter with the largest
ratio is fixed at nominal and the rest analysed again. Such a parameter is reported in words with its
predicted sigma and the combination (``J_id c = -J_f`` on the parameters kept) that changes the residuals
by less than the noise; it is listed in ``practical`` as well as in ``fixed``. Why that bound: a sigma ten
times the typical change is far beyond any manufacturing error the calibration is meant to find (its
estimate would be noise), and beyond it the first-order model of the fit no longer holds over one sigma.
The parameters of the calibrations that do work have predicted sigmas of 0.01 to 2 typical changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .parameters import ParameterVector

#: A scaled singular value below RTOL times the largest one is taken as zero.
RTOL = 1e-6
#: A column whose effect of a typical change (:data:`TYPICAL_CHANGE`) is below ZERO_RTOL times the largest
#: such effect is numerical noise of the finite differences (e.g. the direction of a link between two
#: passive revolute joints of a chain leg, which only its length sets): taken as exactly zero. Without this,
#: scaling the columns to unit length turns that noise into a full-sized, independent column.
ZERO_RTOL = 1e-8
#: Typical change of a parameter by unit, to compare columns of different units for :data:`ZERO_RTOL`.
TYPICAL_CHANGE = {"mm": 1.0, "rad": 1e-2, "1": 1e-2}
#: A kept parameter whose predicted 1-sigma (stated noise) exceeds PRACTICAL_MAX_SIGMA times its
#: :data:`TYPICAL_CHANGE` is practically unidentifiable: fixed at nominal (module docstring).
PRACTICAL_MAX_SIGMA = 10.0


def inverse_normal_matrix(J: np.ndarray) -> np.ndarray:
    """``(J^T J)^-1`` ``(L, L)`` through the SVD of the column-scaled ``J D^-1`` (``D = diag(|J_j|)``):
    ``D^-1 V S^-2 V^T D^-1``, every direction kept, however weak. An inverse (or pseudo-inverse) of the
    unscaled ``J^T J`` loses the weak directions: its cut-off is relative to the largest eigenvalue of a
    matrix whose columns differ by orders of magnitude in units alone (mm against gain), so a weakly
    determined parameter comes out with a tiny variance instead of a huge one. Singular values below
    machine precision times the largest are raised to it (a variance ~1e30 times the others': "not
    determined", but finite); a zero column gets variance 0 (no parameter)."""
    J = np.asarray(J, dtype=float)
    L = J.shape[1]
    if L == 0:
        return np.zeros((0, 0))
    norms = np.linalg.norm(J, axis=0)
    inv_d = np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 0.0)
    _, S, Vt = np.linalg.svd(J * inv_d, full_matrices=False)
    S = np.maximum(S, np.finfo(float).eps * max(S[0], 1e-300) * max(J.shape))
    A = (Vt.T / S) * inv_d[:, None]                   # D^-1 V S^-1
    return A @ A.T


def _priority(pv: ParameterVector) -> list[int]:
    """Order in which the parameters are kept: geometry, gains, offsets, frame (fixed first when coupled)."""
    def rank(name):
        if name.startswith("frame."):
            return 3
        if name.endswith("actuator.offset"):
            return 2
        if name.endswith("actuator.gain"):
            return 1
        return 0
    return sorted(range(len(pv.names)), key=lambda j: (rank(pv.names[j]), j))


@dataclass(frozen=True)
class Identifiability:
    """What a Jacobian ``(m, P)`` can identify.

    ``identified`` / ``fixed``: parameter names; ``combinations``: one sentence per fixed parameter;
    ``null_directions (F, P)``: per fixed parameter the change ``e_f + sum_k c_k e_k`` (physical units) that
    leaves the residuals unchanged (zero rows for parameters fixed by request);
    ``singular_values``: of the column-scaled Jacobian of the identified parameters (descending);
    ``condition``, ``O1``-``O4``: module docstring; ``practical``: the fixed parameters the data
    determine too weakly (module docstring), ``predicted_sigma``: their predicted 1-sigma when they were
    fixed (same order; physical units).
    """

    identified: tuple[str, ...]
    fixed: tuple[str, ...]
    combinations: tuple[str, ...]
    null_directions: np.ndarray
    singular_values: np.ndarray
    condition: float
    O1: float
    O2: float
    O3: float
    O4: float
    practical: tuple[str, ...] = ()
    predicted_sigma: tuple[float, ...] = ()

    def __repr__(self) -> str:
        return (f"Identifiability({len(self.identified)} identified, fixed={list(self.fixed)}, "
                f"condition={self.condition:.4g}, O1={self.O1:.4g})")


def observability_indices(s: np.ndarray, m: int) -> tuple[float, float, float, float]:
    """``(O1, O2, O3, O4)`` of singular values ``s (L,)`` of a scaled Jacobian with ``m`` rows.

    >>> [round(v, 6) for v in observability_indices(np.array([4.0, 1.0]), 4)]
    [1.0, 0.25, 1.0, 0.25]
    """
    s = np.sort(np.asarray(s, dtype=float))[::-1]
    if s.size == 0 or s[-1] <= 0:
        return 0.0, 0.0, 0.0, 0.0
    o1 = float(np.exp(np.mean(np.log(s))) / np.sqrt(m))
    return o1, float(s[-1] / s[0]), float(s[-1]), float(s[-1] ** 2 / s[0])


#: Terms of a combination written out in words before "(+k smaller terms)"; more when they tie with the last.
SHOWN_TERMS = 6


def _terms(names, coef) -> tuple[str, str, int]:
    """``(shown, more, count)``: the terms ``c_k name_k`` of a combination (``|c| > 1e-6``) by decreasing
    ``|c|`` in words, the first :data:`SHOWN_TERMS` and every later one equal to the last shown (to 1e-3
    relative: they would print alike), and ``" (+k smaller terms)"`` for the rest, which are all smaller."""
    terms = [(float(c), n) for c, n in zip(coef, names) if abs(c) > 1e-6]
    terms.sort(key=lambda t: -abs(t[0]))
    k = min(SHOWN_TERMS, len(terms))
    while 0 < k < len(terms) and abs(terms[k][0]) >= abs(terms[k - 1][0]) * (1.0 - 1e-3):
        k += 1
    shown = " ".join(f"{'+' if c > 0 else '-'} {abs(c):.3g} {n}" for c, n in terms[:k])
    more = f" (+{len(terms) - k} smaller term{'s' if len(terms) - k > 1 else ''})" if len(terms) > k else ""
    return shown, more, len(terms)


def _words(names, f, coef) -> str:
    shown, more, count = _terms(names, coef)
    if not count:
        return f"{f} does not change any residual: fixed at nominal"
    return (f"{f} cannot be separated from the others: the change {f} {shown}{more} leaves every residual "
            f"unchanged; {f} fixed at nominal")


def _practical_words(names, f, coef, sigma: float, unit: str, bound: float) -> str:
    shown, more, _ = _terms(names, coef)
    if unit == "rad":
        said, lim = f"{np.degrees(sigma):.3g} deg", f"{np.degrees(bound):.3g} deg"
    else:
        u = "" if unit == "1" else f" {unit}"
        said, lim = f"{sigma:.3g}{u}", f"{bound:.3g}{u}"
    return (f"{f} is practically unidentifiable from these measurements: its predicted 1-sigma would be {said} "
            f"(bound {lim}); the change {f} {shown}{more} changes the residuals by less than the measurement "
            f"noise; {f} fixed at nominal")


def analyse(pv: ParameterVector, J: np.ndarray, rtol: float = RTOL, fixed: tuple[str, ...] = (),
            max_sigma: float | None = None) -> Identifiability:
    """Identifiability of the parameters of ``pv`` from the identification Jacobian ``J (m, P)``.

    ``fixed`` names parameters the user fixes at nominal beforehand; ``max_sigma`` (None: not applied; the
    identification uses :data:`PRACTICAL_MAX_SIGMA`): fix the practically unidentifiable parameters too,
    those whose predicted 1-sigma from the whitened ``J`` exceeds ``max_sigma`` times their
    :data:`TYPICAL_CHANGE` (module docstring). Pose planning leaves it out: its Jacobian is that of the
    candidates, not of the measured points.
    """
    J = np.asarray(J, dtype=float)
    m = J.shape[0]
    if m > J.shape[1]:  # same singular values and column relations, P rows instead of m
        J = np.linalg.qr(J, mode="r")
    norms = np.linalg.norm(J, axis=0)
    effect = norms * np.array([TYPICAL_CHANGE.get(u, 1.0) for u in pv.units])
    norms = np.where(effect > ZERO_RTOL * max(float(effect.max(initial=0.0)), 1e-300), norms, 0.0)
    pre = set(pv.index(fixed))
    keep: list[int] = []
    smax = None
    for j in _priority(pv):
        if j in pre or norms[j] == 0:
            continue
        trial = keep + [j]
        s = np.linalg.svd(J[:, trial] / norms[trial], compute_uv=False)
        smax = s[0] if smax is None else max(smax, s[0])
        if s[-1] > rtol * smax:
            keep = trial
    keep.sort()
    exact_keep = list(keep)
    typical = np.array([TYPICAL_CHANGE.get(u, 1.0) for u in pv.units])
    practical: dict[int, float] = {}
    while max_sigma is not None and keep:
        ratio = np.sqrt(np.clip(np.diag(inverse_normal_matrix(J[:, keep])), 0.0, None)) / typical[keep]
        worst = int(np.argmax(ratio))
        if not ratio[worst] > max_sigma:
            break
        practical[keep[worst]] = float(ratio[worst] * typical[keep[worst]])
        del keep[worst]
    fixed_idx = [j for j in range(len(pv.names)) if j not in keep]
    Jk = J[:, keep]
    sentences = []
    null = np.zeros((len(fixed_idx), len(pv.names)))
    for row, f in enumerate(fixed_idx):
        if f in pre:
            sentences.append(f"{pv.names[f]} fixed at nominal by request")
            continue
        basis = keep if f in practical else exact_keep
        c, *_ = np.linalg.lstsq(J[:, basis], -J[:, f], rcond=None)
        null[row, f] = 1.0
        null[row, basis] = c
        names = [pv.names[k] for k in basis]
        sentences.append(_practical_words(names, pv.names[f], c, practical[f], pv.units[f],
                                          max_sigma * typical[f]) if f in practical
                         else _words(names, pv.names[f], c))
    s = np.linalg.svd(Jk / norms[keep], compute_uv=False) if keep else np.zeros(0)
    o = observability_indices(s, m)
    return Identifiability(identified=tuple(pv.names[k] for k in keep), fixed=tuple(pv.names[f] for f in fixed_idx),
                           combinations=tuple(sentences), null_directions=null, singular_values=s,
                           condition=float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf"),
                           O1=o[0], O2=o[1], O3=o[2], O4=o[3],
                           practical=tuple(pv.names[f] for f in fixed_idx if f in practical),
                           predicted_sigma=tuple(practical[f] for f in fixed_idx if f in practical))
