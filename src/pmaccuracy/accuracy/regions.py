"""Planar regions of positions: a disc, a polygon or an axis-aligned rectangle (mm).

A region of poses is one of these shapes times an orientation interval
(:class:`pmaccuracy.accuracy.global_worst.Region`). Each shape is a closed set of
positions ``(x, y)`` in mm with

* ``contains(x, y)``: a boolean array, vectorized over any shape of inputs;
* ``classify(boxes)``: for boxes ``(m, 4)`` ``[x0, x1, y0, y1]`` (mm), ``INSIDE`` (the
  whole box is in the shape), ``OUTSIDE`` (no point of the box is) or
  ``STRADDLE``; the answer is exact for discs and rectangles and conservative for
  polygons (a box is called ``INSIDE`` or ``OUTSIDE`` only when that is proved;
  boxes that touch an edge, widened by a relative ``1e-12`` for rounding, are
  ``STRADDLE``), which is what a branch and bound needs to stay sound;
* ``nearest(x, y)``: points of the shape, ``(m, 2)``: the point itself when it is in
  the shape, else a point of the boundary nearest to it (for candidate poses);
* ``boundary(n)``: ``(k, 2)`` points on the boundary (for lower bounds);
* ``bounds``: the bounding box ``(x0, x1, y0, y1)``.

Points on the boundary count as inside; for a polygon, "on the boundary" means
within :data:`EDGE_TOL` mm of an edge.

>>> d = Disc((0.0, 0.0), 10.0)
>>> d.contains([0.0, 10.0, 7.5], [0.0, 0.0, 7.5]).tolist()
[True, True, False]
>>> d.classify([[-1, 1, -1, 1], [20, 30, 0, 1], [5, 15, 0, 1]]).tolist()
[1, -1, 0]
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._textfile import read_csv, read_text
from ..errors import ConfigError

#: Box classes of ``classify``.
INSIDE, STRADDLE, OUTSIDE = 1, 0, -1
#: mm: a point this close to a polygon's edge is on the boundary (inside).
EDGE_TOL = 1e-9
#: Relative widening of the boxes tested against a polygon's edges (covers rounding).
WIDEN = 1e-12


def _xy(x, y) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    return x, y


def _boxes(boxes) -> np.ndarray:
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    return b


@dataclass(frozen=True)
class Rect:
    """The rectangle ``[x0, x1] x [y0, y1]`` (mm)."""

    x: tuple[float, float]
    y: tuple[float, float]

    def __post_init__(self):
        x0, x1, y0, y1 = (float(v) for v in (*self.x, *self.y))
        if not np.all(np.isfinite([x0, x1, y0, y1])):
            raise ConfigError("the box must be finite", key="--box")
        if x0 > x1 or y0 > y1:
            raise ConfigError(f"the box is empty or reversed: x0={x0:g} > x1={x1:g} or y0={y0:g} > y1={y1:g}",
                              key="--box")
        object.__setattr__(self, "x", (x0, x1))
        object.__setattr__(self, "y", (y0, y1))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (*self.x, *self.y)

    def contains(self, x, y) -> np.ndarray:
        x, y = _xy(x, y)
        return (x >= self.x[0]) & (x <= self.x[1]) & (y >= self.y[0]) & (y <= self.y[1])

    def classify(self, boxes) -> np.ndarray:
        b = _boxes(boxes)
        out = (b[:, 1] < self.x[0]) | (b[:, 0] > self.x[1]) | (b[:, 3] < self.y[0]) | (b[:, 2] > self.y[1])
        ins = (b[:, 0] >= self.x[0]) & (b[:, 1] <= self.x[1]) & (b[:, 2] >= self.y[0]) & (b[:, 3] <= self.y[1])
        return np.where(out, OUTSIDE, np.where(ins, INSIDE, STRADDLE)).astype(np.int8)

    def nearest(self, x, y) -> np.ndarray:
        x, y = _xy(x, y)
        return np.column_stack([np.clip(x.ravel(), *self.x), np.clip(y.ravel(), *self.y)])

    def boundary(self, n: int = 64) -> np.ndarray:
        return Polygon(((self.x[0], self.y[0]), (self.x[1], self.y[0]), (self.x[1], self.y[1]),
                        (self.x[0], self.y[1]))).boundary(n)

    def describe(self) -> str:
        return f"x in [{self.x[0]:g}, {self.x[1]:g}] mm, y in [{self.y[0]:g}, {self.y[1]:g}] mm"


@dataclass(frozen=True)
class Disc:
    """The closed disc of centre ``(cx, cy)`` and radius ``r >= 0`` (mm).

    >>> Disc((1.0, 2.0), 3.0).bounds
    (-2.0, 4.0, -1.0, 5.0)
    """

    centre: tuple[float, float]
    radius: float

    def __post_init__(self):
        cx, cy = (float(v) for v in self.centre)
        r = float(self.radius)
        if not np.all(np.isfinite([cx, cy, r])):
            raise ConfigError(f"the disc's centre and radius must be finite, got ({cx}, {cy}), {r}", key="--disc")
        if r <= 0:
            raise ConfigError(f"the disc's radius must be > 0 mm, got {r:g}", key="--disc")
        object.__setattr__(self, "centre", (cx, cy))
        object.__setattr__(self, "radius", r)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        (cx, cy), r = self.centre, self.radius
        return (cx - r, cx + r, cy - r, cy + r)

    def contains(self, x, y) -> np.ndarray:
        x, y = _xy(x, y)
        return np.hypot(x - self.centre[0], y - self.centre[1]) <= self.radius

    def classify(self, boxes) -> np.ndarray:
        """Exact: the nearest point of a box farther than ``r`` -> outside; its farthest corner within ``r``
        (with a relative ``1e-12`` margin) -> inside."""
        b = _boxes(boxes)
        (cx, cy), r = self.centre, self.radius
        nx = np.maximum(np.maximum(b[:, 0] - cx, cx - b[:, 1]), 0.0)
        ny = np.maximum(np.maximum(b[:, 2] - cy, cy - b[:, 3]), 0.0)
        fx = np.maximum(np.abs(b[:, 0] - cx), np.abs(b[:, 1] - cx))
        fy = np.maximum(np.abs(b[:, 2] - cy), np.abs(b[:, 3] - cy))
        out = np.hypot(nx, ny) > r * (1 + WIDEN)
        ins = np.hypot(fx, fy) <= r * (1 - WIDEN)
        return np.where(out, OUTSIDE, np.where(ins, INSIDE, STRADDLE)).astype(np.int8)

    def nearest(self, x, y) -> np.ndarray:
        x, y = _xy(x, y)
        dx, dy = x.ravel() - self.centre[0], y.ravel() - self.centre[1]
        d = np.hypot(dx, dy)
        k = np.where(d > self.radius, self.radius * (1 - 1e-12) / np.where(d > 0, d, 1.0), 1.0)
        return np.column_stack([self.centre[0] + k * dx, self.centre[1] + k * dy])

    def boundary(self, n: int = 64) -> np.ndarray:
        t = np.linspace(0, 2 * np.pi, max(int(n), 4), endpoint=False)
        r = self.radius * (1 - 1e-12)
        return np.column_stack([self.centre[0] + r * np.cos(t), self.centre[1] + r * np.sin(t)])

    def describe(self) -> str:
        return f"the disc of centre ({self.centre[0]:g}, {self.centre[1]:g}) mm and radius {self.radius:g} mm"


def _segments_cross(a0, a1, b0, b1) -> np.ndarray:
    """Proper crossings of segments ``a0 a1`` and ``b0 b1`` (arrays ``(..., 2)``), touching included."""
    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    d1, d2 = orient(b0, b1, a0), orient(b0, b1, a1)
    d3, d4 = orient(a0, a1, b0), orient(a0, a1, b1)
    return (d1 * d2 <= 0) & (d3 * d4 <= 0)


@dataclass(frozen=True)
class Polygon:
    """A simple polygon (no self-intersection), vertices ``((x, y), ...)`` in mm, in either order; a closing
    vertex equal to the first is dropped.

    >>> sq = Polygon(((0, 0), (10, 0), (10, 10), (0, 10)))
    >>> sq.contains([5, 11], [5, 5]).tolist()
    [True, False]
    >>> sq.classify([[1, 2, 1, 2], [20, 21, 0, 1], [9, 11, 0, 1]]).tolist()
    [1, -1, 0]
    """

    vertices: tuple[tuple[float, float], ...]

    def __post_init__(self):
        try:
            v = np.asarray(self.vertices, dtype=float)
        except (TypeError, ValueError, OverflowError):   # OverflowError: an integer beyond 1e308
            raise ConfigError("the polygon's vertices must be numbers x, y (mm)", key="--polygon") from None
        if v.ndim != 2 or v.shape[1] != 2:
            raise ConfigError(f"the polygon's vertices must be pairs x, y (mm), got shape {v.shape}",
                              key="--polygon")
        if v.shape[0] > 1 and np.array_equal(v[0], v[-1]):
            v = v[:-1]
        if v.shape[0] < 3:
            raise ConfigError(f"a polygon needs at least 3 vertices, got {v.shape[0]}", key="--polygon")
        if not np.all(np.isfinite(v)):
            raise ConfigError("the polygon's vertices must be finite", key="--polygon")
        n = v.shape[0]
        if np.any(np.all(v == np.roll(v, -1, axis=0), axis=1)):
            raise ConfigError("the polygon has two equal consecutive vertices", key="--polygon")
        a0, a1 = v, np.roll(v, -1, axis=0)
        i, j = np.triu_indices(n, k=1)
        nonadj = (j != i + 1) & ~((i == 0) & (j == n - 1))
        i, j = i[nonadj], j[nonadj]
        hit = _segments_cross(a0[i], a1[i], a0[j], a1[j])
        if np.any(hit):
            k = int(np.argmax(hit))
            raise ConfigError(f"the polygon intersects itself (edges {i[k] + 1} and {j[k] + 1})", key="--polygon")
        x, y = v[:, 0], v[:, 1]
        area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        if abs(area) <= 1e-12 * max(1.0, float(np.ptp(x) * np.ptp(y))):
            raise ConfigError("the polygon has zero area", key="--polygon")
        object.__setattr__(self, "vertices", tuple((float(a), float(b)) for a, b in v))

    @property
    def array(self) -> np.ndarray:
        """Vertices ``(n, 2)`` mm."""
        return np.asarray(self.vertices)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        v = self.array
        return (float(v[:, 0].min()), float(v[:, 0].max()), float(v[:, 1].min()), float(v[:, 1].max()))

    def _edge_distance(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance ``(m,)`` to the boundary and the nearest boundary points ``(m, 2)``."""
        a = self.array
        b = np.roll(a, -1, axis=0)
        d = b - a
        t = ((px[:, None] - a[:, 0]) * d[:, 0] + (py[:, None] - a[:, 1]) * d[:, 1]) / np.sum(d * d, axis=1)
        t = np.clip(t, 0.0, 1.0)
        qx, qy = a[:, 0] + t * d[:, 0], a[:, 1] + t * d[:, 1]
        dist = np.hypot(px[:, None] - qx, py[:, None] - qy)
        k = np.argmin(dist, axis=1)
        rows = np.arange(px.size)
        return dist[rows, k], np.column_stack([qx[rows, k], qy[rows, k]])

    def _even_odd(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        a = self.array
        b = np.roll(a, -1, axis=0)
        ya, yb = a[:, 1], b[:, 1]
        crosses = (ya > py[:, None]) != (yb > py[:, None])
        with np.errstate(divide="ignore", invalid="ignore"):
            xint = a[:, 0] + (py[:, None] - ya) * (b[:, 0] - a[:, 0]) / (yb - ya)
        return (np.count_nonzero(crosses & (px[:, None] < xint), axis=1) % 2) == 1

    def contains(self, x, y) -> np.ndarray:
        x, y = _xy(x, y)
        px, py = x.ravel(), y.ravel()
        if px.size == 0:
            return np.zeros(x.shape, dtype=bool)
        out = self._even_odd(px, py) | (self._edge_distance(px, py)[0] <= EDGE_TOL)
        return out.reshape(x.shape)

    def classify(self, boxes) -> np.ndarray:
        """Conservative: a box that meets an edge (Liang-Barsky clipping of every edge to the box widened by
        :data:`WIDEN`) straddles; any other box lies wholly on one side, decided by its centre."""
        b = _boxes(boxes)
        if b.shape[0] == 0:
            return np.zeros(0, dtype=np.int8)
        w = WIDEN * (np.abs(b).max(axis=1) + (b[:, 1] - b[:, 0]) + (b[:, 3] - b[:, 2]) + 1.0)
        x0, x1, y0, y1 = (b[:, 0] - w)[:, None], (b[:, 1] + w)[:, None], (b[:, 2] - w)[:, None], (b[:, 3] + w)[:, None]
        a = self.array
        e = np.roll(a, -1, axis=0) - a
        px, py, dx, dy = a[:, 0], a[:, 1], e[:, 0], e[:, 1]
        t0 = np.zeros((b.shape[0], a.shape[0]))
        t1 = np.ones_like(t0)
        ok = np.ones_like(t0, dtype=bool)
        for p, q in ((-dx, px - x0), (dx, x1 - px), (-dy, py - y0), (dy, y1 - py)):
            p = np.broadcast_to(p, t0.shape)
            with np.errstate(divide="ignore", invalid="ignore"):
                r = q / p
            ok &= ~((p == 0) & (q < 0))
            t0 = np.where(p < 0, np.maximum(t0, r), t0)
            t1 = np.where(p > 0, np.minimum(t1, r), t1)
        meets = np.any(ok & (t0 <= t1), axis=1)
        centre = self._even_odd(0.5 * (b[:, 0] + b[:, 1]), 0.5 * (b[:, 2] + b[:, 3]))
        return np.where(meets, STRADDLE, np.where(centre, INSIDE, OUTSIDE)).astype(np.int8)

    def nearest(self, x, y) -> np.ndarray:
        x, y = _xy(x, y)
        px, py = x.ravel(), y.ravel()
        if px.size == 0:
            return np.zeros((0, 2))
        inside = self._even_odd(px, py)
        q = self._edge_distance(px, py)[1]
        return np.where(inside[:, None], np.column_stack([px, py]), q)

    def boundary(self, n: int = 64) -> np.ndarray:
        """The vertices and ``n`` points spread along the perimeter (mm)."""
        a = self.array
        e = np.roll(a, -1, axis=0) - a
        length = np.hypot(e[:, 0], e[:, 1])
        s = np.linspace(0, length.sum(), max(int(n), 1), endpoint=False)
        k = np.clip(np.searchsorted(np.cumsum(length), s, side="right"), 0, a.shape[0] - 1)
        t = (s - (np.cumsum(length) - length)[k]) / length[k]
        return np.vstack([a, a[k] + t[:, None] * e[k]])

    def describe(self) -> str:
        pts = ", ".join(f"({x:g}, {y:g})" for x, y in self.vertices[:6])
        more = f", ... ({len(self.vertices)} vertices)" if len(self.vertices) > 6 else ""
        return f"the polygon {pts}{more} mm"


Shape = Rect | Disc | Polygon


def parse_vertices(text: str) -> tuple[tuple[float, float], ...]:
    """``"x1,y1,x2,y2,..."`` (mm) -> vertex pairs; :class:`ConfigError` (key ``--polygon``) otherwise.

    >>> parse_vertices("0,0, 10,0, 0,10")
    ((0.0, 0.0), (10.0, 0.0), (0.0, 10.0))
    """
    parts = [p.strip() for p in str(text).split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise ConfigError(f"expected x1,y1,x2,y2,... in mm or a .csv / .toml file, got {text!r}",
                          key="--polygon") from None
    if len(vals) % 2:
        raise ConfigError(f"an odd number of coordinates ({len(vals)}): give x, y pairs in mm", key="--polygon")
    return tuple(zip(vals[0::2], vals[1::2]))


def load_polygon(path: str | Path) -> Polygon:
    """A polygon from a file: CSV with a header ``x,y`` (mm; ``x_mm,y_mm`` also read), one vertex a row, or
    TOML ``vertices = [[x, y], ...]`` (mm). Errors name the file and the row or key."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such file", key="--polygon")

    def fail(message: str, line: int | None = None) -> ConfigError:
        return ConfigError(f"{path}: {'' if line is None else f'line {line}: '}{message}", key="--polygon")

    if path.suffix.lower() == ".toml":
        try:
            data = tomllib.loads(read_text(path, fail))
        except (tomllib.TOMLDecodeError, RecursionError) as exc:
            raise ConfigError(f"{path}: not valid TOML ({exc or 'nested too deeply'})", key="--polygon") from None
        if "vertices" not in data:
            raise ConfigError(f"{path}: missing key 'vertices' (a list of [x, y] pairs in mm)", key="--polygon")
        v = data["vertices"]
        for k, row in enumerate(v if isinstance(v, list) else [v]):
            if not (isinstance(row, list) and len(row) == 2 and all(isinstance(c, (int, float)) for c in row)):
                raise ConfigError(f"{path}: vertices[{k}] must be a pair [x, y] of numbers (mm), got {row!r}",
                                  key="--polygon")
        try:
            return Polygon(tuple(tuple(r) for r in v))
        except ConfigError as exc:
            raise ConfigError(exc.message, source=str(path), key="--polygon") from None
    if path.suffix.lower() != ".csv":
        raise ConfigError(f"{path}: expected a .csv or .toml file", key="--polygon")
    lines = read_csv(path, fail)
    rows = [row for _, row in lines]
    if not rows:
        raise ConfigError(f"{path}: empty file", key="--polygon")
    header = [h.strip().lower() for h in rows[0]]
    names = [("x", "y"), ("x_mm", "y_mm")]
    cols = next(((header.index(a), header.index(b)) for a, b in names if a in header and b in header), None)
    if cols is None:
        raise ConfigError(f"{path}: the header must name columns x,y (mm), got {rows[0]}", key="--polygon")
    verts = []
    for k, row in lines[1:]:
        if not any(c.strip() for c in row):
            continue
        try:
            verts.append((float(row[cols[0]]), float(row[cols[1]])))
        except (ValueError, IndexError):
            raise fail(f"expected numbers x, y (mm), got {row}", k) from None
    try:
        return Polygon(tuple(verts))
    except ConfigError as exc:
        raise ConfigError(exc.message, source=str(path), key="--polygon") from None
