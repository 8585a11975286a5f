"""Cutting the error set: the four-piece split, the children of a source, and the branch and bound over
pieces until the gap closes (package docstring, "Cutting the error set")."""

from __future__ import annotations

import math

import numpy as np

from .closure import _Model, _objective, _take_many, exact_change
from .error_set import QUANTITIES, SourceSet, argsupport, project, sector_rect
from .remainder import _certify, _contains_zero, _continues, _point_box, _recentre


def _split_bounds(model: _Model, sets, scale: float, k: int, anchor_M: np.ndarray | None = None,
                  anchor_b: np.ndarray | None = None, anchor_b0: np.ndarray | None = None) -> dict:
    """Certified bounds over the error set cut into ``2^k`` pieces (then the largest over the pieces).

    The ``k`` interval sources that turn the chain the most (score ``eps sum_m |r_m0| |alpha_m|``, summed
    over the poses) are halved: each piece is a product of the same kinds of sets, centred at ``delta_c``
    (``+-eps/2`` on the halved sources). About its centre, the exact closure solved there (Newton,
    :func:`exact_change`, its residual kept in ``F0``), the certificate of :func:`_certify` applies unchanged
    with half the widths, so its remainder terms are smaller; the bound of the whole set is the largest of
    the pieces' (each is an upper bound over its piece, and the pieces cover ``S``). Every piece must pass
    :func:`_continues` against the whole set's certificate (``anchor_M`` ``(N, 9, n)``, ``anchor_b`` ``(N,
    9)``, about ``Dz = 0`` at ``delta = 0``) or, since every piece contains ``delta = 0``, against the
    commanded assembly's box ``anchor_b0`` ``(N, 9)`` (:func:`_point_box`); NaN or None: none. Returns
    ``upper`` ``{q: (N,)}``, ``certified`` ``(N,)`` and ``rejected`` ``(N,)`` (pieces certified but rejected).
    """
    N, n = model.z0.shape[0], model.n
    J = model.jacobian(np.zeros((N, 9 + n)))
    with np.errstate(all="ignore"):
        M = -np.linalg.solve(J[..., :9], J[..., 9:])
    alpha = np.einsum("nmj,njk->nmk", model.tg[..., :9], M) + model.tg[..., 9:]
    score = np.nansum(np.abs(model.r0)[..., None] * np.abs(alpha), axis=(0, 1))  # (n,)
    intervals = [s for s in sets if s.kind == "interval"]
    chosen = sorted(intervals, key=lambda s: -s.eps * score[s.cols[0]])[:k]
    if not chosen:
        return {"upper": {q: np.full(N, np.nan) for q in QUANTITIES}, "certified": np.zeros(N, dtype=bool),
                "rejected": np.zeros(N, dtype=int)}
    half = tuple(SourceSet(s.kind, s.leg, s.joint, s.field, s.eps / 2 if s in chosen else s.eps, s.cols,
                           s.block_length) for s in sets)
    if anchor_b is None:
        anchor_M, anchor_b = np.zeros((N, 9, n)), np.full((N, 9), np.nan)
    models, offsets, goods, centres = [], [], [], []
    for signs in np.ndindex(*(2,) * len(chosen)):
        centre = np.zeros(n)
        for s, sg in zip(chosen, signs):
            centre[s.cols[0]] = (s.eps / 2) * (1.0 if sg else -1.0)
        centre = np.broadcast_to(centre, (N, n))
        dz = exact_change(model, M, centre)
        good = np.all(np.isfinite(dz), axis=-1)
        dz = np.where(good[:, None], dz, 0.0)
        models.append(_recentre(model, np.concatenate([dz, centre], axis=-1)))
        offsets.append(dz)
        goods.append(good)
        centres.append(centre)
    # all pieces of all poses in one vectorized certificate
    stacked = _Model(**{f: (np.concatenate([getattr(m, f) for m in models]) if f not in ("leg_of", "n")
                            else getattr(model, f)) for f in ("r0", "t0", "rg", "tg", "leg_of", "aff0", "affg",
                                                               "ang0", "angg", "n", "z0")})
    part = _certify(stacked, half, scale, offset=np.concatenate(offsets))
    P = len(models)
    if anchor_b0 is None:
        anchor_b0 = np.full((N, 9), np.nan)
    cont = np.stack([np.array([bool(_continues(
        offsets[p][i:i + 1], part["b_centre"][p * N + i:p * N + i + 1], centres[p][i:i + 1],
        {"dz": np.zeros(9), "M": anchor_M[i], "b": anchor_b[i], "centre": np.zeros(n), "b0": anchor_b0[i]},
        part["M"][p * N + i:p * N + i + 1], part["b"][p * N + i:p * N + i + 1],
        _contains_zero(half, centres[p][i:i + 1]))[0]) for i in range(N)]) for p in range(P)])  # (P, N)
    pc = np.stack(goods) & part["certified"].reshape(P, N)
    rejected = np.sum(pc & ~cont, axis=0)
    certified = np.all(pc & cont, axis=0)
    upper = {q: np.where(certified, np.max(part["upper"][q].reshape(P, N), axis=0), np.nan) for q in QUANTITIES}
    return {"upper": upper, "certified": certified, "rejected": rejected}


#: A cut disk is first covered by this many sector pieces (:func:`_children`); each leaves the disk by at most
#: ``1 / cos(pi / DISK_SECTORS) - 1`` (8 %) of its radius, only at its corners.
DISK_SECTORS = 8
#: A pose with no certificate yet (whole set and first cut) may bound this many times ``max_pieces`` pieces, once
#: some piece is used within the first ``max_pieces`` (otherwise it stops there).
REFUSED_BUDGET = 3
#: Directions of ``|dp|`` tried at the extreme points of every accepted piece for the best feasible values.
PIECE_DIRECTIONS = 16


def _children(s: SourceSet, c: np.ndarray) -> list[tuple[SourceSet, np.ndarray]]:
    """The cut of one source of a piece: smaller sets that cover it, each with its centre in the source's own
    parameters (``c`` ``(len(cols),)``: the source's centre in the piece, mm or rad).

    * interval: two halves (a partition), centres ``c +- eps/2``;
    * rhombus ``|L tau +- 2 sigma| <= 2 eps``, a square in its edge coordinates ``(2 sigma +- L tau) / (2 eps)``,
      quartered: four rhombi of half-width ``eps/2`` centred at ``c + (+-eps/2, 0)`` and ``c + (0, +-eps/L)``;
    * disk: :data:`DISK_SECTORS` sectors ``r <= eps``, ``|t - theta_j| <= pi / DISK_SECTORS``, each as the
      rectangle of :func:`sector_rect` that contains it;
    * rect (a sector): its sector halved across its longer side of the rectangle, in angle (two sectors of
      half the opening) or in radius (``[r1, rm]``, ``[rm, r2]``).

    Disk and rect children overlap and stick out of the disk by their corners: they cover the source's set,
    which is all an upper bound needs (the largest bound over a cover bounds the maximum over the set).

    >>> [c.tolist() for _, c in _children(SourceSet("interval", 0, 0, "turn", 0.002, (0,)), np.zeros(1))]
    [[-0.001], [0.001]]
    """
    c = np.asarray(c, dtype=float)
    if s.kind == "interval":
        h = s.eps / 2
        child = SourceSet(s.kind, s.leg, s.joint, s.field, h, s.cols)
        return [(child, c + np.array([-h])), (child, c + np.array([h]))]
    if s.kind == "rhombus":
        e, t = s.eps / 2, s.eps / s.block_length
        child = SourceSet(s.kind, s.leg, s.joint, s.field, e, s.cols, s.block_length)
        return [(child, c + np.array(o)) for o in ((e, 0.0), (-e, 0.0), (0.0, t), (0.0, -t))]
    if s.kind == "disk":
        half = math.pi / DISK_SECTORS
        return [sector_rect(s, 2 * half * j, half, 0.0, s.eps, c) for j in range(DISK_SECTORS)]
    if s.kind == "rect":
        theta, half, r1, r2, ox, oy = s.sector
        if s.eps_t >= s.eps:
            return [sector_rect(s, theta + sg * half / 2, half / 2, r1, r2, (ox, oy)) for sg in (-1, 1)]
        rm = (r1 + r2) / 2
        return [sector_rect(s, theta, half, a, b, (ox, oy)) for a, b in ((r1, rm), (rm, r2))]
    raise ValueError(f"a {s.kind} source is not cut")


def _contains(sets, centre: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Whether each of ``points`` ``(P, n)`` lies in the piece of shape ``sets`` centred at ``centre`` ``(n,)``."""
    return _contains_zero(sets, centre[None] - points)


def _piece_bounds(model1: _Model, M1: np.ndarray, sets, centres: np.ndarray, scale: float,
                  target: dict | None = None) -> dict:
    """Certificates of one pose (``model1``: one pose) over pieces of the same shape ``sets`` centred at
    ``centres`` ``(P, n)``: the closure solved exactly at each centre (Newton from the first-order solution
    ``M1`` ``(1, 9, n)``), the model expanded there and certified (:func:`_certify` with ``offset``; refined
    only above ``target``).

    Returns ``upper`` ``{q: (P,)}`` (inf where not certified), ``certified`` ``(P,)`` and per piece ``dz``
    ``(P, 9)`` (exact change at the centre), ``M`` ``(P, 9, n)``, ``b`` ``(P, 9)`` (the box: every ``delta``
    of the piece has one solution in ``|Dz - dz - M (delta - c)| <= b``, unique there) and ``bc`` ``(P, 9)``
    (the box of the solution at the centre). Whether that solution is the commanded assembly's continuation
    is decided by the caller (:func:`_branch_and_bound`)."""
    P = centres.shape[0]
    big = _take_many(model1, np.zeros(P, dtype=int))
    dz = exact_change(big, np.repeat(M1, P, axis=0), centres)
    good = np.all(np.isfinite(dz), axis=-1)
    dz = np.where(good[:, None], dz, 0.0)
    part = _certify(_recentre(big, np.concatenate([dz, centres], axis=-1)), sets, scale, offset=dz, target=target)
    cert = good & part["certified"]
    return {"upper": {q: np.where(cert, part["upper"][q], np.inf) for q in QUANTITIES}, "certified": cert,
            "dz": dz, "M": part["M"], "b": part["b"], "bc": part["b_centre"]}


def _point_anchor(model1: _Model, point: np.ndarray, guess: np.ndarray, scale: float):
    """A proven solution box at one point ``delta = point`` ``(n,)``: Newton's method from ``guess`` ``(9,)``,
    then :func:`_point_box` about the solution; returns ``(dz (9,), b (9,))`` (NaN where not proven)."""
    D = np.concatenate([guess, point])[None]
    moved = _recentre(model1, D)
    corr = exact_change(moved, np.zeros((1, 9, model1.n)), np.zeros((1, model1.n)))[0]
    if not np.all(np.isfinite(corr)):
        return np.full(9, np.nan), np.full(9, np.nan)
    dz = guess + corr
    b = _point_box(_recentre(model1, np.concatenate([dz, point])[None]), scale)[0]
    return dz, b


def _branch_and_bound(model1: _Model, sets, scale: float, lower: dict, gap: float = 0.005,
                      max_pieces: int = 96, anchor: dict | None = None, min_progress: int | None = None) -> dict:
    """Adaptive cutting of the error set of one pose until every bound is within ``gap`` of the best feasible
    value (module docstring, "Cutting the set" and "Continuation check").

    Pieces are products of the sources' sets with some sources cut (:func:`_children`: intervals halved,
    rhombi quartered, disks covered by sectors, sectors halved); each is certified by :func:`_piece_bounds`.
    A certified piece is *used* once its solution is shown to be the continuation of the commanded assembly:
    some point ``d`` of the piece has a proven continuation box (an *anchor*) inside the piece's box at ``d``
    (then, by the piece's uniqueness, its solution at ``d`` is the continuation, hence on the whole connected
    piece). Anchors: the commanded assembly at ``d = 0`` (``anchor["b0"]``, and the whole set's certified box
    ``anchor["b"]`` if any), the centre box of every used piece, and the centre ``c_P`` of every cut piece
    (contained in all of its children) once a used piece contains it: Newton at ``c_P`` from that piece's
    prediction and a point certificate (:func:`_point_anchor`) inside that piece's box.

    Rounds: every piece whose bound (its own if used, capped by its used ancestors') exceeds ``(1 + gap)``
    times the best feasible value is cut along its source of largest turning weight (``eps sum_m |r_m0|
    |alpha_m|``, interval, rhombus, disk or sector), worst first, until all are within or ``max_pieces``
    pieces have been certified, or no piece is used after ``min_progress`` (default ``max_pieces``). The best
    feasible values (``lower`` ``{q: float}``, raised as it goes) come from the extreme points of every used
    piece (the argsupport of its first-order rows and of :data:`PIECE_DIRECTIONS` directions of ``(dx, dy)``,
    projected onto ``S``), solved exactly from the piece's centre and kept only in the piece and inside its
    box there.

    Returns ``upper`` ``{q: float}`` (the largest capped bound over the pieces, which cover ``S``; inf while a
    piece has neither its own nor an ancestor's), ``lower`` ``{q: float}`` and ``worst`` ``{q: (n,) or
    None}`` (the configuration attaining it when it was raised here), ``pieces`` (leaves), ``bounded``
    (pieces certified in all) and ``rejected`` (leaves certified but never shown to be the continuation).
    """
    n = model1.n
    min_progress = max_pieces if min_progress is None else min_progress
    J = model1.jacobian(np.zeros((1, 9 + n)))
    M1 = -np.linalg.solve(J[..., :9], J[..., 9:])
    alpha = np.einsum("nmj,njk->nmk", model1.tg[..., :9], M1) + model1.tg[..., 9:]
    score = np.sum(np.abs(model1.r0)[..., None] * np.abs(alpha), axis=(0, 1))  # (n,)

    def weight(s):
        if s.kind == "interval":
            return s.eps * score[s.cols[0]]
        if s.kind in ("disk", "rect"):
            return max(s.eps, s.eps_t) * math.hypot(score[s.cols[0]], score[s.cols[1]])
        return max(s.eps * score[s.cols[0]], 2 * s.eps / s.block_length * score[s.cols[1]])

    anchor = anchor or {}
    anchors = []  # proven continuation boxes: (point (n,), lo (9,), hi (9,))
    for key in ("b0", "b"):
        b = np.asarray(anchor.get(key, np.full(9, np.nan)), dtype=float)
        if np.all(np.isfinite(b)):
            anchors.append((np.zeros(n), -b, b))
    lower = {q: float(lower[q]) if np.isfinite(lower[q]) else 0.0 for q in QUANTITIES}
    worst = {q: None for q in QUANTITIES}
    cut_points = []  # centres of the pieces cut so far, to be anchored when a used piece contains them
    anchored = set()

    # a leaf: dict(sets, centre, upper {q}, cert (dz, M, b, bc) or None, used)
    def bound(groups, target=None, caps=None):
        out = []
        for cs, C in groups:
            pb = _piece_bounds(model1, M1, cs, C, scale, target)
            for p in range(len(C)):
                cert = (pb["dz"][p], pb["M"][p], pb["b"][p], pb["bc"][p]) if pb["certified"][p] else None
                out.append({"sets": cs, "centre": C[p], "upper": {q: float(pb["upper"][q][p]) for q in QUANTITIES},
                            "cert": cert, "used": False, "cap": dict(caps[len(out)]) if caps else
                            {q: np.inf for q in QUANTITIES}})
        return out

    def box_at(leaf, d):
        dz, Mp, b, _ = leaf["cert"]
        mid = dz + Mp @ (d - leaf["centre"])
        return mid - b, mid + b

    def settle(leaves):
        """Use every certified leaf that contains an anchor inside its box; used leaves add anchors."""
        fresh, changed = [], True
        while changed:
            changed = False
            for leaf in leaves:
                if leaf["used"] or leaf["cert"] is None or not anchors:
                    continue
                pts = np.array([a[0] for a in anchors])
                inside = np.flatnonzero(_contains(leaf["sets"], leaf["centre"], pts))
                for a in inside:
                    d, lo, hi = anchors[a]
                    blo, bhi = box_at(leaf, d)
                    if np.all(np.isfinite(blo)) and np.all(lo >= blo) and np.all(hi <= bhi):
                        break
                else:
                    continue
                leaf["used"], changed = True, True
                fresh.append(leaf)
                dz, _, _, bc = leaf["cert"]
                if np.all(np.isfinite(bc)):
                    anchors.append((leaf["centre"].copy(), dz - bc, dz + bc))
                for k, p in enumerate(cut_points):
                    if k in anchored or not _contains(leaf["sets"], leaf["centre"], p[None])[0]:
                        continue
                    blo, bhi = box_at(leaf, p)
                    zp, bp = _point_anchor(model1, p, (blo + bhi) / 2, scale)
                    if np.all(np.isfinite(bp)) and np.all(zp - bp >= blo) and np.all(zp + bp <= bhi):
                        anchors.append((p.copy(), zp - bp, zp + bp))
                        anchored.add(k)
        return fresh

    def raise_lower(fresh):
        """The best feasible values at the extreme points of the newly used pieces (solved from each piece)."""
        if not fresh:
            return
        ang = 2 * np.pi * np.arange(PIECE_DIRECTIONS) / PIECE_DIRECTIONS
        u = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
        for leaf in fresh:
            dz, Mp, b, _ = leaf["cert"]
            rows = np.concatenate([Mp[:3], -Mp[:3], u @ Mp[:2]])  # (6 + K, n)
            cand = project(sets, argsupport(leaf["sets"], rows) + leaf["centre"])
            moved = _recentre(model1, np.concatenate([dz, leaf["centre"]])[None])
            sol = exact_change(moved, Mp[None], (cand - leaf["centre"])[:, None, :])[:, 0] + dz  # (R, 9)
            pred = dz + (cand - leaf["centre"]) @ Mp.T
            # in the piece and inside its box there: the continuation (module docstring, "Continuation check")
            ok = np.all(np.abs(sol - pred) <= b, axis=-1) & _contains(leaf["sets"], leaf["centre"], cand)
            vals = np.stack([_objective(q, sol) for q in QUANTITIES])  # (4, R)
            vals = np.where(ok[None] & np.isfinite(vals), vals, -np.inf)
            for qi, q in enumerate(QUANTITIES):
                r = int(np.argmax(vals[qi]))
                if vals[qi, r] > lower[q]:
                    lower[q], worst[q] = float(vals[qi, r]), cand[r].copy()

    def effective(leaf, q):
        """A leaf's bound: its own if used, capped by its used ancestors' (each holds over the leaf's part)."""
        return min(leaf["upper"][q] if leaf["used"] else np.inf, leaf["cap"][q])

    leaves = bound([(tuple(sets), np.zeros((1, n)))])
    used = 1
    raise_lower(settle(leaves))
    while True:
        target = {q: lower[q] * (1 + gap) for q in QUANTITIES}

        def excess(leaf):
            return max(effective(leaf, q) / target[q] - 1 if target[q] > 0 else
                       (np.inf if effective(leaf, q) > 0 else -1.0) for q in QUANTITIES)

        ex = [excess(leaf) for leaf in leaves]
        over = [i for i, e in enumerate(ex) if e > 0]
        if not over:
            break
        if used >= min_progress and not any(leaf["used"] for leaf in leaves):
            break  # no piece shown to be the continuation yet: more cutting is unlikely to help
        over.sort(key=lambda i: -ex[i])
        plan, cost = [], 0
        for i in over:
            leaf = leaves[i]
            ps = leaf["sets"]
            k = max(range(len(ps)), key=lambda j: weight(ps[j]))
            cols = list(ps[k].cols)
            kids = _children(ps[k], leaf["centre"][cols])
            if used + cost + len(kids) > max_pieces:
                break
            plan.append((i, k, cols, kids))
            cost += len(kids)
        if not plan:
            break
        groups = {}  # children of the same shape are certified together (one vectorized certificate)
        for i, k, cols, kids in plan:
            leaf = leaves[i]
            cut_points.append(leaf["centre"].copy())
            cap = {q: effective(leaf, q) for q in QUANTITIES}
            for child, cc in kids:
                cs = leaf["sets"][:k] + (child,) + leaf["sets"][k + 1:]
                C = leaf["centre"].copy()
                C[cols] = cc
                groups.setdefault(cs, []).append((C, cap))
        drop = {i for i, *_ in plan}
        used += cost
        leaves = [x for i, x in enumerate(leaves) if i not in drop] + bound(
            [(cs, np.array([c for c, _ in Cs])) for cs, Cs in groups.items()], target,
            [cap for Cs in groups.values() for _, cap in Cs])
        # the cut pieces' centres may now lie in used pieces: anchor them, then use what they reach
        for leaf in leaves:
            if leaf["used"]:
                for k, p in enumerate(cut_points):
                    if k in anchored or not _contains(leaf["sets"], leaf["centre"], p[None])[0]:
                        continue
                    blo, bhi = box_at(leaf, p)
                    zp, bp = _point_anchor(model1, p, (blo + bhi) / 2, scale)
                    if np.all(np.isfinite(bp)) and np.all(zp - bp >= blo) and np.all(zp + bp <= bhi):
                        anchors.append((p.copy(), zp - bp, zp + bp))
                        anchored.add(k)
        raise_lower(settle(leaves))
    upper = {q: max(effective(leaf, q) for leaf in leaves) for q in QUANTITIES}
    return {"upper": upper, "lower": lower, "worst": worst, "pieces": len(leaves), "bounded": used,
            "rejected": sum(1 for leaf in leaves if leaf["cert"] is not None and not leaf["used"])}
