"""Measurement from photos end to end: a manifest of images -> the measurement CSV of ``experiment compare``.

Manifest (CSV, UTF-8, one row per photo)::

    image,point,x_nom,y_nom,phi_nom_deg,push
    photos/p1_px.png,P1,0,0,0,+x
    ...

``image`` is a path (relative paths are relative to the manifest's folder);
``point`` a label; ``x_nom, y_nom, phi_nom_deg`` the commanded pose (mm, mm,
deg); ``push`` one of ``+x,-x,+y,-y,+r,-r``. Every point needs each push
exactly once, with the same nominal pose on its six rows. The manifest is
checked completely (columns, numbers, pushes, files present) before any image
is measured; a photo that cannot be measured stops the batch with an error
naming the photo and its manifest line. No row is ever skipped.

Each reading is the measured pose in the calibration's frame; its orientation
(a square's angle is only known modulo 90 deg) is taken as the value nearest
the nominal orientation: ``phi_nom + remainder(phi - phi_nom, 90 deg)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from .._textfile import read_csv
from ..errors import VisionError
from ._util import DEFAULT_SPACING_MM
from ..experiment import NOMINAL_TOLERANCE, PUSHES
from ..experiment import Measurements
from .images import load_image
from .pose import measure_pose

#: Columns of a manifest, in order.
MANIFEST_COLUMNS = ("image", "point", "x_nom", "y_nom", "phi_nom_deg", "push")


@dataclass(frozen=True)
class ManifestRow:
    """One photo: its ``path``, manifest ``line``, ``point`` label, nominal pose ``(x mm, y mm, phi rad)``, ``push``."""

    path: Path
    line: int
    point: str
    nominal: tuple[float, float, float]
    push: str


def read_manifest(path: str | Path) -> list[ManifestRow]:
    """Read and check a manifest (module docstring); every problem is a :class:`VisionError` naming file and line."""

    path = Path(path)
    src = str(path)
    if not path.exists():
        raise VisionError(f"{src}: no such manifest file")
    lines = read_csv(path, lambda message, line: VisionError(
        f"{src}: {'' if line is None else f'line {line}: '}{message}"))
    header = lines[0][1] if lines else None
    body = lines[1:]
    if header is None or [h.strip() for h in header] != list(MANIFEST_COLUMNS):
        got = ",".join(header) if header else "nothing"
        raise VisionError(f"{src}: line 1: header must be {','.join(MANIFEST_COLUMNS)!r}, got {got!r}")
    rows: list[ManifestRow] = []
    first: dict[str, ManifestRow] = {}
    seen: dict[tuple[str, str], int] = {}
    for line, raw in body:
        if not raw or all(not c.strip() for c in raw):
            continue
        where = f"{src}: line {line}"
        if len(raw) != len(MANIFEST_COLUMNS):
            raise VisionError(f"{where}: expected {len(MANIFEST_COLUMNS)} values ({','.join(MANIFEST_COLUMNS)}), "
                              f"got {len(raw)}")
        image, point, xs, ys, phis, push = (c.strip() for c in raw)
        if not image:
            raise VisionError(f"{where}: empty image path")
        if not point:
            raise VisionError(f"{where}: empty point label")
        if push not in PUSHES:
            raise VisionError(f"{where}: push {push!r} is not one of {', '.join(PUSHES)}")
        values = []
        for name, text in (("x_nom", xs), ("y_nom", ys), ("phi_nom_deg", phis)):
            try:
                value = float(text)
            except ValueError:
                raise VisionError(f"{where}: column {name}: not a number: {text!r}") from None
            if not math.isfinite(value):
                raise VisionError(f"{where}: column {name}: must be finite, got {text!r}")
            values.append(value)
        file = Path(image) if Path(image).is_absolute() else path.parent / image
        row = ManifestRow(file, line, point, (values[0], values[1], math.radians(values[2])), push)
        if (point, push) in seen:
            raise VisionError(f"{where}: point {point}: push {push} repeated (already on line {seen[point, push]})")
        seen[point, push] = line
        ref = first.setdefault(point, row)
        if (abs(values[0] - ref.nominal[0]) > NOMINAL_TOLERANCE or abs(values[1] - ref.nominal[1]) > NOMINAL_TOLERANCE
                or abs(math.remainder(values[2] - math.degrees(ref.nominal[2]), 360.0)) > NOMINAL_TOLERANCE):
            raise VisionError(f"{where}: point {point}: nominal pose differs from the one on line {ref.line}")
        rows.append(row)
    if not rows:
        raise VisionError(f"{src}: the manifest lists no images")
    for point, ref in first.items():
        missing = [p for p in PUSHES if (point, p) not in seen]
        if missing:
            raise VisionError(f"{src}: line {ref.line}: point {point}: missing push(es) {', '.join(missing)}; every "
                              f"point needs {', '.join(PUSHES)}")
    absent = [r for r in rows if not r.path.is_file()]
    if absent:
        more = f" (and {len(absent) - 1} more)" if len(absent) > 1 else ""
        raise VisionError(f"{src}: line {absent[0].line}: no such image file {absent[0].path}{more}")
    return rows


def measure_batch(rows: Sequence[ManifestRow], calibration: Any, *, height_mm: float = 0.0,
                  spacing_mm: float = DEFAULT_SPACING_MM, polarity: str = "dark",
                  progress: Callable[[int, int], None] | None = None) -> tuple[Any, list[dict[str, Any]]]:
    """Measure every photo of a checked manifest; returns the :class:`~pmaccuracy.experiment.Measurements` and one
    record per photo (image, point, push, pose, 1-sigma uncertainty).

    The first photo that fails raises :class:`VisionError` naming it and its manifest line.
    """

    calibration.plane_at(height_mm)  # refuses a height a single-view calibration cannot measure, before any work
    order: dict[str, int] = {}
    nominal: list[tuple[float, float, float]] = []
    readings: list[np.ndarray] = []
    records: list[dict[str, Any]] = []
    for n, row in enumerate(rows):  # one photo at a time
        try:
            pose = measure_pose(load_image(row.path), calibration=calibration, height_mm=height_mm,
                                spacing_mm=spacing_mm, polarity=polarity)
        except VisionError as exc:
            text = str(exc)
            prefix = f"{row.path}: "
            text = text[len(prefix):] if text.startswith(prefix) else text
            raise VisionError(f"{row.path} (manifest line {row.line}): {text}") from None
        if row.point not in order:
            order[row.point] = len(order)
            nominal.append(row.nominal)
            readings.append(np.full((len(PUSHES), 3), np.nan))
        phi = row.nominal[2] + math.remainder(pose.phi - row.nominal[2], math.pi / 2)
        readings[order[row.point]][PUSHES.index(row.push)] = (pose.x, pose.y, phi)
        rec = {"image": str(row.path), "point": row.point, "push": row.push, "x": pose.x, "y": pose.y,
               "phi_deg": math.degrees(phi), "residual_mm": pose.residual_mm}
        if pose.sigma is not None:
            rec["uncertainty"] = pose.as_dict()["uncertainty"]
        records.append(rec)
        if progress is not None:
            progress(n + 1, len(rows))
    measurements = Measurements(np.array(list(order)), np.array(nominal), np.stack(readings),
                                source="vision batch")
    return measurements, records
