"""Independent dense search of the exact (nonlinear) worst-case pose errors over an error set (tests only).

Written from the loop-closure equations alone: the error configurations are inserted into the legs' chains
and the three loops are closed exactly by :func:`error_reference._solve` (extended-precision Newton, its own
chain model); nothing here imports ``pmaccuracy``. The maximum of ``|dx|``, ``|dy|``, ``|dphi|`` and
``|dp| = |(dx, dy)|`` over the error set is searched by

1. the first-order worst vertices of the reference itself (:func:`error_reference.worst_case`, central
   differences of the exact closure) and their negatives,
2. ``n_random`` random configurations, mostly on the boundary of every source's set (interval ends, disk
   circles, rhombus vertices and edges), some inside,
3. from the best start of each quantity, a greedy dense coordinate search: every source in turn is replaced
   by each of its dense samples (``dense`` points: the whole interval, ``4 dense`` points of the circle plus
   a ring inside, the rhombus vertices, its edges and interior points), all single replacements are solved
   as one batch, the best improvement is kept, until none improves.

Every value returned is attained by a feasible configuration, so it is a lower bound of the true maximum;
being dense, it is close to it. Units: mm and rad. Sets as in :mod:`error_reference`: radial/position
disk ``|d| <= eps``; angular/direction/actuator/length interval; lateral rhombus
``|L tau +- 2 sigma| <= 2 eps``.
"""

from __future__ import annotations

import numpy as np

import error_reference as eref

QUANTITIES = ("dx", "dy", "dphi", "dp")


def scaled_spec(spec: dict, factor: float) -> dict:
    """A clearance/tolerance file dict with every half-width times ``factor`` (``block_length`` kept)."""
    return {"legs": [{"joints": [{k: (v if k == "block_length" else v * factor) for k, v in j.items()}
                                 for j in leg["joints"]]} for leg in spec["legs"]]}


def source_samples(kind: str, eps: float, block_length, dense: int) -> np.ndarray:
    """Dense samples ``(S, m)`` of one source's set: interval ``m = 1``, disk and rhombus ``m = 2``."""
    if kind == "interval":
        return np.linspace(-eps, eps, dense)[:, None]
    if kind == "disk":
        a = np.linspace(0, 2 * np.pi, 4 * dense, endpoint=False)
        ring = np.linspace(0, 2 * np.pi, dense, endpoint=False)
        return np.concatenate([eps * np.column_stack([np.cos(a), np.sin(a)]),
                               0.5 * eps * np.column_stack([np.cos(ring), np.sin(ring)]), [[0.0, 0.0]]])
    tilt = 2 * eps / block_length
    verts = np.array([[eps, 0.0], [0.0, tilt], [-eps, 0.0], [0.0, -tilt]])
    t = np.linspace(0, 1, dense, endpoint=False)[:, None]
    edges = np.concatenate([verts[i] + t * (verts[(i + 1) % 4] - verts[i]) for i in range(4)])
    return np.concatenate([edges, 0.5 * edges, [[0.0, 0.0]]])


def random_points(sources, n: int, rng) -> np.ndarray:
    """``(n, nvars)`` random configurations: each source on its boundary (80 %) or inside (20 %)."""
    nv = sum(len(cols) for _, _, cols, _ in sources)
    out = np.zeros((n, nv))
    for kind, eps, cols, L in sources:
        inside = rng.uniform(size=n) < 0.2
        if kind == "interval":
            v = np.where(inside, rng.uniform(-eps, eps, n), eps * rng.choice([-1.0, 1.0], n))
            out[:, cols[0]] = v
        elif kind == "disk":
            a = rng.uniform(0, 2 * np.pi, n)
            r = np.where(inside, eps * np.sqrt(rng.uniform(size=n)), eps)
            out[:, cols[0]], out[:, cols[1]] = r * np.cos(a), r * np.sin(a)
        else:
            tilt = 2 * eps / L
            verts = np.array([[eps, 0.0], [0.0, tilt], [-eps, 0.0], [0.0, -tilt]])
            i = rng.integers(0, 4, n)
            t = np.where(rng.uniform(size=n) < 0.5, 0.0, rng.uniform(size=n))[:, None]
            p = verts[i] + t * (verts[(i + 1) % 4] - verts[i])
            p = np.where(inside[:, None], p * rng.uniform(size=(n, 1)), p)
            out[:, cols[0]], out[:, cols[1]] = p[:, 0], p[:, 1]
    return out


def exact_errors(robot, pose, q0, vars_, values: np.ndarray) -> np.ndarray:
    """Exact pose errors ``(B, 3)`` (mm, mm, rad; dphi wrapped) of the flat configurations ``values (B, n)``."""
    X = eref._solve(robot, pose, q0, eref._to_arrays(vars_, values)) - np.asarray(pose, float)
    X[:, 2] = eref.wrap(X[:, 2])
    return X.astype(float)


def objective(q: str, E: np.ndarray) -> np.ndarray:
    if q == "dp":
        return np.hypot(E[:, 0], E[:, 1])
    return np.abs(E[:, QUANTITIES.index(q)])


def dense_search(robot_data, pose, clearances, tolerances=None, *, n_random: int = 1500, dense: int = 12,
                 max_steps: int = 12, seed: int = 0) -> dict:
    """The largest exact ``|dx|, |dy|, |dphi|, |dp|`` found over the error set (module docstring).

    ``robot_data``: robot dict (TOML, degrees); ``pose`` ``(3,)`` mm, mm, rad; ``clearances`` /
    ``tolerances``: file-format dicts. Returns ``{q: value}`` plus ``"first_order_vertex"`` ``{q: the
    larger exact value at the reference's first-order worst vertex and its negative}``, ``"first_order"``
    (the reference's first-order maxima) and ``"argmax"`` ``{q: flat configuration}``.
    """
    rng = np.random.default_rng(seed)
    robot = eref.as_robot(robot_data)
    pose = np.asarray(pose, float)
    wc = eref.worst_case(robot_data, pose, clearances, tolerances)
    vars_, spec = wc["variables"], wc["spec"]
    sources = eref._sources(spec, vars_)
    q0 = eref.inverse_kinematics(robot, pose)
    out = {"first_order": {q: wc[f"{q}_max"] for q in QUANTITIES}, "first_order_vertex": {}, "argmax": {}}
    if not vars_:
        out.update({q: 0.0 for q in QUANTITIES})
        return out
    starts = np.concatenate([np.array([s * wc["argmax_flat"][q] for q in QUANTITIES for s in (1, -1)]),
                             random_points(sources, n_random, rng)])
    E = exact_errors(robot, pose, q0, vars_, starts)
    samples = [(cols, source_samples(kind, eps, L, dense)) for kind, eps, cols, L in sources]
    for qi, q in enumerate(QUANTITIES):
        vals = objective(q, E)
        out["first_order_vertex"][q] = float(max(vals[2 * qi], vals[2 * qi + 1]))
        k = int(np.argmax(vals))
        best, best_val = starts[k].copy(), float(vals[k])
        for _ in range(max_steps):
            batch = []
            for cols, S in samples:
                B = np.repeat(best[None], len(S), axis=0)
                B[:, cols] = S
                batch.append(B)
            batch = np.concatenate(batch)
            v = objective(q, exact_errors(robot, pose, q0, vars_, batch))
            j = int(np.argmax(v))
            if v[j] <= best_val * (1 + 1e-13):
                break
            best, best_val = batch[j].copy(), float(v[j])
        out[q] = best_val
        out["argmax"][q] = best
    return out
