"""An interactive 3D view of a workspace for a web page: self-contained, offline, plain JavaScript.

:func:`view3d_html` returns an HTML fragment (a ``<div>`` holding a ``<canvas>``, a reset button, a caption,
the points as inline JSON and an inline ``<script>``) that draws the boundary points of a
:class:`~pmaccuracy.kinematics.workspace3d.Workspace3D` (and optionally the robot as line segments) in an
orthographic 3D projection on a canvas 2D context: drag (mouse or one finger) to rotate, wheel or two-finger
pinch to zoom, "Reset view" to go back. No network, no external library, no CDN: it works from a file opened
offline. Points are coloured by the third coordinate (legend on the right) and an axis triad with names and
units sits in the lower left corner. :func:`write_view3d_page` writes the fragment as a standalone page.
"""

from __future__ import annotations

import hashlib
import html
import json
import os
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..kinematics.workspace3d import Workspace3D
from .workspace3d_figures import MAX_VIEW_POINTS, subsample, value_with_error

#: Colour scale of the heights (viridis at 9 stops), shared by the points and the legend.
PALETTE = ["#440154", "#472d7b", "#3b528b", "#2c728e", "#21918c", "#28ae80", "#5ec962", "#addc30", "#fde725"]

_SCRIPT = r"""
(function () {
  var root = document.getElementById(%(id)s);
  var data = JSON.parse(root.querySelector('script.pm-view3d-data').textContent);
  var canvas = root.querySelector('canvas');
  var ctx = canvas.getContext('2d');
  var P = data.points, n = P.length / 3, S = data.segments || [];
  var lo = data.lo, hi = data.hi, mid = [0, 1, 2].map(function (d) { return 0.5 * (lo[d] + hi[d]); });
  var scale = data.scale;          // per-axis factors that bring the axes to a common scale
  var radius = 0.5 * Math.sqrt([0, 1, 2].reduce(function (s, d) {
    var w = (hi[d] - lo[d]) * scale[d]; return s + w * w; }, 0)) || 1;
  var pal = data.palette, zlo = data.zrange[0], zhi = data.zrange[1];   // the points' colours: the region's z only
  var colour = new Array(n);
  for (var i = 0; i < n; i++) {
    var f = zhi > zlo ? (P[3 * i + 2] - zlo) / (zhi - zlo) : 0.5;
    colour[i] = pal[Math.max(0, Math.min(pal.length - 1, Math.round(f * (pal.length - 1))))];
  }
  var HOME = {yaw: -0.9, pitch: 0.45, zoom: 1.0}, view = {yaw: HOME.yaw, pitch: HOME.pitch, zoom: HOME.zoom};
  var W = 0, H = 0, order = new Array(n), sx = new Float64Array(n), sy = new Float64Array(n),
      sd = new Float64Array(n);
  function rot(x, y, z) {      // world (z up) -> screen x right, y up, depth towards the viewer
    var cy = Math.cos(view.yaw), syw = Math.sin(view.yaw), cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    var a = cy * x - syw * y, b = syw * x + cy * y;
    return [a, cp * z - sp * b, sp * z + cp * b];
  }
  function legendWidth() { return W < 520 ? 64 : 84; }
  function project(x, y, z) {
    var q = rot((x - mid[0]) * scale[0], (y - mid[1]) * scale[1], (z - mid[2]) * scale[2]);
    var usable = Math.min(W - legendWidth(), H) * 0.45 * view.zoom / radius;
    return [(W - legendWidth()) / 2 + q[0] * usable, H / 2 - q[1] * usable, q[2]];
  }
  function resize() {
    var dpr = window.devicePixelRatio || 1;
    W = Math.max(200, canvas.parentNode.clientWidth);
    H = Math.round(Math.max(340, Math.min(W * 0.72, 640)));
    canvas.style.width = W + 'px'; canvas.style.height = H + 'px';
    canvas.width = Math.round(W * dpr); canvas.height = Math.round(H * dpr);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    draw();
  }
  function text(s, x, y, align, base) {
    ctx.textAlign = align || 'left'; ctx.textBaseline = base || 'middle'; ctx.fillText(s, x, y);
  }
  function draw() {
    ctx.clearRect(0, 0, W, H);
    ctx.fillStyle = '#ffffff'; ctx.fillRect(0, 0, W, H);
    for (var i = 0; i < n; i++) {
      var p = project(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
      sx[i] = p[0]; sy[i] = p[1]; sd[i] = p[2]; order[i] = i;
    }
    order.sort(function (a, b) { return sd[a] - sd[b]; });
    var size = W < 520 ? 1.6 : 2.0, last = null;
    for (var k = 0; k < n; k++) {
      var j = order[k];
      if (colour[j] !== last) { ctx.fillStyle = colour[j]; last = colour[j]; }
      ctx.fillRect(sx[j] - size / 2, sy[j] - size / 2, size, size);
    }
    if (S.length) {
      ctx.strokeStyle = '#c0392b'; ctx.lineWidth = 2.5; ctx.beginPath();
      for (var s = 0; s < S.length; s++) {
        var a = project(S[s][0][0], S[s][0][1], S[s][0][2]), b = project(S[s][1][0], S[s][1][1], S[s][1][2]);
        ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]);
      }
      ctx.stroke();
    }
    triad(); legend();
  }
  function triad() {
    var narrow = W < 520, ox = narrow ? 34 : 46, oy = H - (narrow ? 34 : 46), len = narrow ? 22 : 30;
    var cols = ['#d62728', '#2ca02c', '#1f77b4'];
    ctx.font = (narrow ? '12px' : '13px') + ' sans-serif'; ctx.lineWidth = 2;
    for (var d = 0; d < 3; d++) {
      var e = [0, 0, 0]; e[d] = 1;
      var q = rot(e[0], e[1], e[2]);
      ctx.strokeStyle = cols[d]; ctx.beginPath(); ctx.moveTo(ox, oy);
      ctx.lineTo(ox + q[0] * len, oy - q[1] * len); ctx.stroke();
      ctx.fillStyle = cols[d];
      var tx = ox + q[0] * (len + 9), ty = oy - q[1] * (len + 9);
      text(data.labels[d], tx, ty, q[0] < -0.3 ? 'right' : (q[0] > 0.3 ? 'left' : 'center'));
    }
  }
  function legend() {
    var lw = legendWidth(), x = W - lw + 8, top = 34, h = Math.min(180, H - 90), bw = 12;
    var g = ctx.createLinearGradient(0, top + h, 0, top);
    for (var k = 0; k < pal.length; k++) g.addColorStop(k / (pal.length - 1), pal[k]);
    ctx.fillStyle = g; ctx.fillRect(x, top, bw, h);
    ctx.strokeStyle = '#555'; ctx.lineWidth = 1; ctx.strokeRect(x, top, bw, h);
    ctx.fillStyle = '#222'; ctx.font = '12px sans-serif';
    text(data.labels[2], W - 4, top - 17, 'right');
    text(data.zticks[1], x + bw + 4, top, 'left');
    text(data.zticks[0], x + bw + 4, top + h, 'left');
  }
  var drag = null, pinch = null;
  function start(x, y) { drag = {x: x, y: y, yaw: view.yaw, pitch: view.pitch}; }
  function move(x, y) {
    if (!drag) return;
    view.yaw = drag.yaw + (x - drag.x) * 0.01;
    view.pitch = Math.max(-1.55, Math.min(1.55, drag.pitch + (y - drag.y) * 0.01));
    draw();
  }
  function zoomBy(f) { view.zoom = Math.max(0.2, Math.min(20, view.zoom * f)); draw(); }
  canvas.addEventListener('mousedown', function (e) { start(e.clientX, e.clientY); e.preventDefault(); });
  window.addEventListener('mousemove', function (e) { move(e.clientX, e.clientY); });
  window.addEventListener('mouseup', function () { drag = null; });
  canvas.addEventListener('wheel', function (e) { e.preventDefault(); zoomBy(Math.exp(-e.deltaY * 0.0015)); },
                          {passive: false});
  function spread(t) { return Math.hypot(t[0].clientX - t[1].clientX, t[0].clientY - t[1].clientY); }
  canvas.addEventListener('touchstart', function (e) {
    if (e.touches.length === 1) { start(e.touches[0].clientX, e.touches[0].clientY); pinch = null; }
    else if (e.touches.length === 2) { drag = null; pinch = {d: spread(e.touches), zoom: view.zoom}; }
    e.preventDefault();
  }, {passive: false});
  canvas.addEventListener('touchmove', function (e) {
    if (pinch && e.touches.length === 2) {
      view.zoom = Math.max(0.2, Math.min(20, pinch.zoom * spread(e.touches) / Math.max(pinch.d, 1))); draw();
    } else if (e.touches.length === 1) { move(e.touches[0].clientX, e.touches[0].clientY); }
    e.preventDefault();
  }, {passive: false});
  canvas.addEventListener('touchend', function () { drag = null; pinch = null; });
  root.querySelector('button.pm-view3d-reset').addEventListener('click', function () {
    view.yaw = HOME.yaw; view.pitch = HOME.pitch; view.zoom = HOME.zoom; draw();
  });
  window.addEventListener('resize', resize);
  resize();
})();
"""

def _json(obj) -> str:
    """JSON safe inside a ``<script>`` element (no ``</``, no ``<!--``)."""
    return json.dumps(obj, separators=(",", ":")).replace("<", "\\u003c").replace(">", "\\u003e")


def _check_segments(robot_segments) -> np.ndarray:
    if robot_segments is None:
        return np.zeros((0, 2, 3))
    seg = np.asarray(robot_segments, dtype=float)
    if seg.ndim != 3 or seg.shape[1:] != (2, 3) or not np.isfinite(seg).all():
        raise ConfigError(f"must be finite line segments of shape (k, 2, 3), got shape {seg.shape}",
                          key="robot_segments")
    return seg


def _digits(ws: Workspace3D) -> int:
    """Decimals that keep the points to a thousandth of a cell (the JSON stays small)."""
    return int(max(0, np.ceil(-np.log10(float(ws.cell.min()) * 1e-3))))


def view3d_html(ws: Workspace3D, *, title: str, robot_segments=None, max_points: int = MAX_VIEW_POINTS,
                element_id: str | None = None) -> str:
    """A self-contained HTML fragment showing the boundary points of ``ws`` in 3D (see the module's text).

    At most ``max_points`` points are embedded (a reproducible random subset; the caption says how many of
    how many). ``robot_segments`` ``(k, 2, 3)``: line segments drawing the robot at a pose, in red. The points
    are in a ``<script type="application/json" class="pm-view3d-data">`` element (key ``points``: x, y, z
    flat). ``element_id``: the ``<div>``'s id (default: from a hash of the content, so that several views on
    one page do not clash). Axes are shown at one scale when the three units agree, else each stretched to
    the same size.
    An empty workspace raises :class:`~pmaccuracy.errors.EmptyWorkspaceError`.
    """
    ws.require_nonempty()
    seg = _check_segments(robot_segments)
    shown = subsample(ws.boundary_points, max_points)
    digits = _digits(ws)
    bb = ws.bounding_box
    lo, hi = bb[:, 0].copy(), bb[:, 1].copy()
    if len(seg):
        lo = np.minimum(lo, seg.reshape(-1, 3).min(axis=0))
        hi = np.maximum(hi, seg.reshape(-1, 3).max(axis=0))
    width = np.maximum(hi - lo, 1e-12)
    scale = np.ones(3) if len(set(ws.units)) == 1 else width.max() / width
    labels = [f"{n} [{u}]" if u else n for n, u in zip(ws.names, ws.units)]
    payload = {
        "points": np.round(shown, digits).ravel().tolist(),
        "segments": np.round(seg, digits).tolist(),
        "lo": lo.tolist(), "hi": hi.tolist(), "scale": scale.tolist(),
        "labels": labels, "palette": PALETTE,
        "zrange": bb[2].tolist(),     # the colour scale: the region's third coordinate (not the robot's)
        "zticks": [f"{bb[2][0]:.4g}", f"{bb[2][1]:.4g}"],
    }
    if element_id is None:           # the same view gets the same id; different views, different ids
        element_id = "pm-view3d-" + hashlib.sha1(_json([title, payload]).encode()).hexdigest()[:12]
    units = "\u00b7".join(ws.units) if len(set(ws.units)) > 1 else f"{ws.units[0]}\u00b3"
    robot = " The robot at a pose is drawn in red." if len(seg) else ""
    subset = f" (a random subset: at most {max_points})" if len(shown) < len(ws.boundary_points) else ""
    caption = (f"{len(shown)} of {len(ws.boundary_points)} boundary points shown{subset}"
               f", coloured by {ws.names[2]}; volume {value_with_error(ws.volume, ws.volume_error)} {units}.{robot} "
               f"Drag to rotate, use the wheel or pinch to zoom.")
    script = _SCRIPT % {"id": _json(element_id)}
    return (f'<div class="pm-view3d" id="{html.escape(element_id)}" data-points="{len(shown)}" '
            f'style="max-width:960px;margin:1em 0;font-family:sans-serif">\n'
            f'<div style="font-weight:bold;font-size:1.1em;margin-bottom:0.3em">{html.escape(title)}</div>\n'
            f'<div style="position:relative;width:100%"><canvas role="img" aria-label="{html.escape(title)}" '
            f'style="display:block;touch-action:none;border:1px solid #ccc;cursor:grab"></canvas></div>\n'
            f'<div style="margin-top:0.4em"><button type="button" class="pm-view3d-reset">Reset view</button></div>\n'
            f'<p style="font-size:0.9em;color:#333;margin:0.4em 0">{html.escape(caption)}</p>\n'
            f'<script type="application/json" class="pm-view3d-data">{_json(payload)}</script>\n'
            f'<script>{script}</script>\n</div>\n')


def write_view3d_page(ws: Workspace3D, path: str | os.PathLike, title: str, *, robot_segments=None,
                      max_points: int = MAX_VIEW_POINTS) -> Path:
    """Write :func:`view3d_html` as a standalone HTML page (UTF-8) at ``path``; returns the path."""
    path = Path(os.fspath(path))
    if path.suffix.lower() not in (".html", ".htm"):
        raise ConfigError(f"must end in .html, got {path.name!r}", source=os.fspath(path), key="path")
    body = view3d_html(ws, title=title, robot_segments=robot_segments, max_points=max_points)
    page = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            f"<title>{html.escape(title)}</title>\n</head>\n"
            "<body style=\"margin:0.8em\">\n" + body + "</body>\n</html>\n")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page, encoding="utf-8")
    return path
