"""Kinematic calibration from photos (issue 23): the calibration poses photographed, measured, identified.

:func:`render_calibration_photos` photographs the platform markers of a (true) robot at each command of a
plan: its pose is the exact model's (:func:`pmaccuracy.accuracy.calibration.simulate.measure`, no camera
noise: the photo's own pixel noise and blur are the camera), rendered by the flat test camera
(:func:`pmaccuracy.vision.render.render_platform`: a plain scale ``mm_per_pixel``, origin at the image
centre, so the measurement frame is the image's) into ``FOLDER/<point>.png``, with a manifest
``FOLDER/manifest.csv``::

    image,point,q1_deg,q2_deg,q3_deg,x_nom,y_nom,phi_nom_deg

(the plan's command columns, as in the calibration CSV, and the nominal pose of each command).

:func:`measure_calibration_photos` measures every photo of such a manifest as ``vision pose`` and
``vision batch`` do (:func:`pmaccuracy.vision.pose.measure_pose`: blobs, the 2 x 2 marker square, its
pose and 1-sigma uncertainty from the centres' noise) and returns the calibration data: commands, the
measured poses (a square's orientation, known modulo 90 deg, taken nearest ``phi_nom_deg``) and the photos' sigmas, ready for :func:`~pmaccuracy.accuracy.calibration
.identify.identify` (or written by :func:`~pmaccuracy.accuracy.calibration.data.write_calibration_csv` for
``calibrate identify``). ``pmaccuracy vision batch`` reads such a manifest too, with a calibration file or a
plain scale (:func:`read_calibration_manifest`, :func:`measure_calibration_manifest`,
:func:`write_calibration_readings`: the command columns copied as written, so no robot is needed), and writes
the calibration CSV that ``calibrate identify --data`` reads.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..accuracy.calibration.data import CalibrationData, command_columns
from ..accuracy.calibration.parameters import actuators
from ..accuracy.calibration.simulate import measure
from .._textfile import read_csv
from ..errors import MeasurementFileError, VisionError
from ._util import DEFAULT_SPACING_MM
from .images import MAX_IMAGE_PIXELS, load_image, save_image
from .pose import measure_pose
from .render import render_platform

#: Scale of the flat camera of the calibration photos, mm per pixel, and the margin kept around the poses, mm.
PHOTO_MM_PER_PIXEL = 0.25
PHOTO_MARGIN_MM = 30.0
#: Largest side of a calibration photo, px (a larger workspace needs a coarser scale): a square photo within
#: the readers' pixel limit (:data:`pmaccuracy.vision.images.MAX_IMAGE_PIXELS`), so it is refused before rendering.
MAX_PHOTO_PX = math.isqrt(MAX_IMAGE_PIXELS)


def photo_shape(poses: np.ndarray, mm_per_pixel: float = PHOTO_MM_PER_PIXEL,
                margin_mm: float = PHOTO_MARGIN_MM) -> tuple[int, int]:
    """Square image ``(H, W)`` px centred on the measurement frame's origin that holds ``poses (N, 3)``
    with ``margin_mm`` around them; :class:`VisionError` above :data:`MAX_PHOTO_PX`.

    >>> photo_shape(np.array([[10.0, -20.0, 0.1]]))
    (400, 400)
    """
    half = float(np.max(np.abs(np.asarray(poses, dtype=float)[:, :2]))) + margin_mm
    n = int(2 * math.ceil(half / mm_per_pixel))
    if n > MAX_PHOTO_PX:
        raise VisionError(f"the poses span +-{half:.4g} mm: photos of {n} px at {mm_per_pixel:g} mm per pixel, more "
                          f"than {MAX_PHOTO_PX} px (take a coarser scale, --mm-per-pixel)")
    return n, n


def render_calibration_photos(pv, true_values: np.ndarray, commands: np.ndarray, reference: np.ndarray, folder,
                              *, mm_per_pixel: float = PHOTO_MM_PER_PIXEL, clearances=None, seed: int = 0,
                              spacing_mm: float = DEFAULT_SPACING_MM, marker_radius_mm: float | None = None,
                              noise_sigma: float = 0.01) -> tuple[Path, np.ndarray]:
    """Photograph the robot ``true_values`` at ``commands (N, A)`` (module docstring); ``reference (N, 3)``
    picks the assembly mode (the nominal poses); ``marker_radius_mm`` defaults to 1.5 mm or 6 px, whichever is
    larger (the detector needs round blobs of a few pixels). Returns the manifest's path and the true poses ``(N, 3)``
    (mm, mm, rad; NaN rows where the robot cannot reach: no photo, no manifest row)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    commands = np.asarray(commands, dtype=float)
    poses = measure(pv, np.asarray(true_values, dtype=float), commands, reference, noise=(0.0, 0.0, 0.0),
                    clearances=clearances, seed=seed)
    ok = np.all(np.isfinite(poses), axis=1)
    if not np.any(ok):
        raise VisionError("the robot reaches none of the planned poses: nothing to photograph")
    shape = photo_shape(poses[ok], mm_per_pixel)
    if marker_radius_mm is None:
        marker_radius_mm = max(1.5, 6.0 * mm_per_pixel)
    kinds_r = np.array([kind == "R" for kind, _ in actuators(pv.robot)])
    cmd_file = np.where(kinds_r, np.degrees(commands), commands)
    rows = []
    for n in np.flatnonzero(ok):
        name = f"{n + 1}.png"
        x, y, phi = poses[n]
        image = render_platform(x, y, phi, shape=shape, mm_per_pixel=mm_per_pixel, spacing_mm=spacing_mm,
                                marker_radius_mm=marker_radius_mm, noise_sigma=noise_sigma, seed=seed + int(n))
        save_image(folder / name, image)
        nom = np.asarray(reference, dtype=float)[n]
        rows.append([name, str(n + 1)] + [repr(float(v)) for v in cmd_file[n]] +
                    [repr(float(nom[0])), repr(float(nom[1])), repr(math.degrees(nom[2]))])
    with open(folder / "manifest.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(["image", "point", *command_columns(pv.robot), "x_nom", "y_nom", "phi_nom_deg"])
        writer.writerows(rows)
    return folder / "manifest.csv", poses


def measure_calibration_photos(manifest, pv, *, mm_per_pixel: float = PHOTO_MM_PER_PIXEL,
                               calibration=None, height_mm: float = 0.0,
                               spacing_mm: float = DEFAULT_SPACING_MM) -> CalibrationData:
    """Measure the photos of a calibration manifest (module docstring) -> :class:`CalibrationData` with the
    photos' own 1-sigma uncertainties. ``calibration`` (a :class:`~pmaccuracy.vision.calibration.Calibration`)
    replaces the flat camera's scale. Raises :class:`~pmaccuracy.errors.MeasurementFileError` naming the
    manifest line of a malformed row and :class:`~pmaccuracy.errors.VisionError` naming a photo that cannot
    be measured."""
    manifest = Path(manifest)
    want = command_columns(pv.robot)
    lines = read_csv(manifest, MeasurementFileError)
    rows = [row for _, row in lines]
    header = [h.strip() for h in rows[0]] if rows else []
    missing = [c for c in ("image", "point", *want, "phi_nom_deg") if c not in header]
    if missing:
        raise MeasurementFileError(f"header must name image,point,{','.join(want)},phi_nom_deg (missing "
                                   f"{','.join(missing)})",
                                   source=str(manifest), key="line 1")
    kinds_r = np.array([kind == "R" for kind, _ in actuators(pv.robot)])
    labels, commands, paths, phi_nom = [], [], [], []
    for line, row in lines[1:]:
        if not row or all(not c.strip() for c in row):
            continue
        try:
            vals = [float(row[header.index(c)]) for c in want]
            phi_nom.append(math.radians(float(row[header.index("phi_nom_deg")])))
        except (ValueError, IndexError):
            raise MeasurementFileError(f"{','.join(want)},phi_nom_deg must be numbers", source=str(manifest),
                                       key=f"line {line}") from None
        labels.append(row[header.index("point")].strip())
        commands.append(np.where(kinds_r, np.radians(vals), vals))
        paths.append(manifest.parent / row[header.index("image")].strip())
    if not labels:
        raise MeasurementFileError("no photos listed", source=str(manifest))
    commands = np.array(commands)
    poses, sigmas = [], []
    for label, path, ref in zip(labels, paths, phi_nom):
        try:
            pose = measure_pose(load_image(path), calibration=calibration,
                                mm_per_pixel=None if calibration is not None else mm_per_pixel,
                                height_mm=height_mm, spacing_mm=spacing_mm)
        except VisionError as exc:
            raise VisionError(f"{path} (point {label}): {exc}") from None
        phi = ref + math.remainder(pose.phi - ref, math.pi / 2)
        poses.append((pose.x, pose.y, phi))
        if pose.sigma is None or not np.all(np.isfinite(pose.sigma)) or min(pose.sigma) <= 0:
            raise VisionError(f"{path} (point {label}): the photo gives no uncertainty of its pose")
        sigmas.append(pose.sigma)
    return CalibrationData(tuple(labels), commands, np.array(poses), np.array(sigmas), str(manifest))


def photo_measurer(folder, *, mm_per_pixel: float = PHOTO_MM_PER_PIXEL, clearances=None):
    """A ``measure_with`` for :func:`~pmaccuracy.accuracy.calibration.simulate.simulate_calibration`: the
    planned poses photographed into ``folder`` (:func:`render_calibration_photos`) and measured from the
    photos (:func:`measure_calibration_photos`)."""
    def measure_with(pv, true, commands, reference, seed):
        manifest, _ = render_calibration_photos(pv, true, commands, reference, folder, mm_per_pixel=mm_per_pixel,
                                                clearances=clearances, seed=seed)
        return measure_calibration_photos(manifest, pv, mm_per_pixel=mm_per_pixel)
    return measure_with


# ------------------------------------------------------------------ the calibration manifest in `vision batch`
#: Columns of a calibration manifest besides its command columns (``q{i}`` mm, ``q{i}_deg`` deg).
CALIBRATION_MANIFEST_COLUMNS = ("image", "point", "x_nom", "y_nom", "phi_nom_deg")
_COMMAND_COLUMN = re.compile(r"q[1-9][0-9]*(_deg)?$")


def is_calibration_manifest(header) -> bool:
    """Whether a manifest's ``header`` (column names) is a calibration manifest (module docstring: ``image,
    point``, command columns ``q1 | q1_deg, ...``, ``x_nom, y_nom, phi_nom_deg``, no ``push``) rather than the
    clearance experiment's (:mod:`pmaccuracy.vision.batch`, with a ``push`` column).

    >>> is_calibration_manifest("image,point,q1_deg,q2_deg,q3_deg,x_nom,y_nom,phi_nom_deg".split(","))
    True
    >>> is_calibration_manifest("image,point,x_nom,y_nom,phi_nom_deg,push".split(","))
    False
    """
    names = [str(h).strip() for h in header]
    return ("push" not in names and all(c in names for c in CALIBRATION_MANIFEST_COLUMNS)
            and any(_COMMAND_COLUMN.match(n) for n in names))


@dataclass(frozen=True)
class CalibrationPhoto:
    """One photo of a calibration manifest: its ``path``, manifest ``line``, ``point`` label, ``commands`` as
    written (mm or deg, in the order of the manifest's command columns) and ``nominal`` pose (mm, mm, rad)."""

    path: Path
    line: int
    point: str
    commands: tuple[float, ...]
    nominal: tuple[float, float, float]


def read_calibration_manifest(path) -> tuple[tuple[str, ...], list[CalibrationPhoto]]:
    """The command column names (in file order) and the photos of a calibration manifest, checked completely
    (header, numbers, repeated points, files present) before any photo is measured; every problem is a
    :class:`~pmaccuracy.errors.VisionError` naming the file and the line."""
    path = Path(path)
    src = str(path)
    if not path.exists():
        raise VisionError(f"{src}: no such manifest file")
    lines = read_csv(path, lambda message, line: VisionError(
        f"{src}: {'' if line is None else f'line {line}: '}{message}"))
    header = [h.strip() for h in lines[0][1]] if lines else []
    body = lines[1:]
    if not is_calibration_manifest(header):
        raise VisionError(f"{src}: line 1: a calibration manifest's header names image,point, the command columns "
                          f"(q1 or q1_deg, ...) and x_nom,y_nom,phi_nom_deg, got {','.join(header) or 'nothing'!r}")
    commands = tuple(h for h in header if _COMMAND_COLUMN.match(h))
    if len(set(commands)) != len(commands) or len({c.split("_")[0] for c in commands}) != len(commands):
        raise VisionError(f"{src}: line 1: a command column is repeated ({','.join(commands)})")
    numeric = (*commands, "x_nom", "y_nom", "phi_nom_deg")
    photos: list[CalibrationPhoto] = []
    seen: dict[str, int] = {}
    for line, raw in body:
        if not raw or all(not c.strip() for c in raw):
            continue
        where = f"{src}: line {line}"
        if len(raw) != len(header):
            raise VisionError(f"{where}: expected {len(header)} values ({','.join(header)}), got {len(raw)}")
        row = dict(zip(header, (c.strip() for c in raw)))
        if not row["image"]:
            raise VisionError(f"{where}: empty image path")
        if not row["point"]:
            raise VisionError(f"{where}: empty point label")
        if row["point"] in seen:
            raise VisionError(f"{where}: point {row['point']} repeated (already on line {seen[row['point']]})")
        seen[row["point"]] = line
        values = {}
        for name in numeric:
            try:
                values[name] = float(row[name])
            except ValueError:
                raise VisionError(f"{where}: column {name}: not a number: {row[name]!r}") from None
            if not math.isfinite(values[name]):
                raise VisionError(f"{where}: column {name}: must be finite, got {row[name]!r}")
        file = Path(row["image"]) if Path(row["image"]).is_absolute() else path.parent / row["image"]
        photos.append(CalibrationPhoto(file, line, row["point"], tuple(values[c] for c in commands),
                                       (values["x_nom"], values["y_nom"], math.radians(values["phi_nom_deg"]))))
    if not photos:
        raise VisionError(f"{src}: the manifest lists no images")
    absent = [p for p in photos if not p.path.is_file()]
    if absent:
        more = f" (and {len(absent) - 1} more)" if len(absent) > 1 else ""
        raise VisionError(f"{src}: line {absent[0].line}: no such image file {absent[0].path}{more}")
    return commands, photos


def measure_calibration_manifest(path, *, calibration=None, mm_per_pixel: float | None = None,
                                 height_mm: float = 0.0, spacing_mm: float = DEFAULT_SPACING_MM,
                                 polarity: str = "dark") -> tuple[tuple[str, ...], list[dict]]:
    """Measure every photo of a calibration manifest (:func:`read_calibration_manifest`) as ``vision pose``
    does (:func:`~pmaccuracy.vision.pose.measure_pose`, with ``calibration`` or a plain ``mm_per_pixel``
    scale, exactly one): returns the command column names and one record per photo, ``point``, the commands
    as written, the pose ``x, y`` (mm) and ``phi_deg`` (the square's orientation, known modulo 90 deg, taken
    nearest ``phi_nom_deg``), ``sigma_x, sigma_y`` (mm) and ``sigma_phi_deg``, ``image`` and
    ``residual_mm``: the rows of the calibration CSV (:func:`write_calibration_readings`). The first photo that
    cannot be measured (or gives no uncertainty) raises :class:`~pmaccuracy.errors.VisionError` naming it and
    its manifest line."""
    if (calibration is None) == (mm_per_pixel is None):
        raise VisionError("give either a calibration or mm_per_pixel (exactly one)")
    commands, photos = read_calibration_manifest(path)
    if calibration is not None:
        calibration.plane_at(height_mm)   # refuses a height the calibration cannot measure, before any work
    records = []
    for photo in photos:   # one photo at a time
        try:
            pose = measure_pose(load_image(photo.path), calibration=calibration, mm_per_pixel=mm_per_pixel,
                                height_mm=height_mm, spacing_mm=spacing_mm, polarity=polarity)
            if pose.sigma is None or not np.all(np.isfinite(pose.sigma)) or min(pose.sigma) <= 0:
                raise VisionError("the photo gives no uncertainty of its pose")
        except VisionError as exc:
            text = str(exc)
            prefix = f"{photo.path}: "
            text = text[len(prefix):] if text.startswith(prefix) else text
            raise VisionError(f"{photo.path} (manifest line {photo.line}): {text}") from None
        phi = photo.nominal[2] + math.remainder(pose.phi - photo.nominal[2], math.pi / 2)
        rec = {"point": photo.point, **dict(zip(commands, photo.commands)), "x": pose.x, "y": pose.y,
               "phi_deg": math.degrees(phi), "sigma_x": pose.sigma[0], "sigma_y": pose.sigma[1],
               "sigma_phi_deg": math.degrees(pose.sigma[2]), "image": str(photo.path),
               "residual_mm": pose.residual_mm}
        records.append(rec)
    return commands, records


def write_calibration_readings(path, commands: tuple[str, ...], records: list[dict]) -> None:
    """Write the records of :func:`measure_calibration_manifest` as a calibration CSV
    (:mod:`pmaccuracy.accuracy.calibration.data`: ``point``, the command columns, ``x, y, phi_deg``,
    ``sigma_x, sigma_y, sigma_phi_deg``), which ``calibrate identify --data`` reads as it is."""
    names = ("point", *commands, "x", "y", "phi_deg", "sigma_x", "sigma_y", "sigma_phi_deg")
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(names)
        for rec in records:
            writer.writerow([rec["point"]] + [repr(float(rec[n])) for n in names[1:]])
