"""``pmaccuracy vision ...``: camera calibration, platform pose from photos, batches, test images (paper Sec. 5).

Sub-commands:

* ``calibrate PLANE.png [VIEW.png ...] --out CAL.toml`` - fit the camera (Zhang with >= 3 images, else a plane
  homography with radial distortion);
* ``pose IMAGE (--calibration CAL.toml | --mm-per-pixel S) [--marker-height-mm H]`` - pose of the 2 x 2 markers,
  with its 1-sigma uncertainty;
* ``batch MANIFEST.csv --calibration CAL.toml --out MEASUREMENTS.csv`` - photos -> measurement CSV;
* ``detect IMAGE`` - list the detected dot centres in pixels;
* ``render-sheet`` / ``render-pose`` / ``render-batch`` - seeded test images from the physically modelled camera
  (or the flat one).

Heavy libraries (OpenCV, SciPy, scikit-image) are imported inside the command functions.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..errors import PmAccuracyError
from . import _common

DEFAULT_SPACING_MM = 20.0  # the paper's sheet and marker square (pmaccuracy.vision.DEFAULT_SPACING_MM)


def _positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = _common.finite_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive: {text!r}")
    return value


def _nonnegative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = _common.finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must not be negative: {text!r}")
    return value


def _nonnegative_int(text: str) -> int:
    """argparse type: a whole number >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must not be negative: {text!r}")
    return value


def _add_detection(p: argparse.ArgumentParser) -> None:
    p.add_argument("--polarity", choices=("dark", "light"), default="dark",
                   help="dark dots on a light background (default) or light dots on a dark one")


def _add_spacing(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--spacing-mm", type=_positive_float, default=DEFAULT_SPACING_MM,
                   help=f"{what} in mm (default: {DEFAULT_SPACING_MM:g})")


def _add_height(p: argparse.ArgumentParser) -> None:
    p.add_argument("--marker-height-mm", type=_common.finite_float, default=0.0, metavar="H",
                   help="height of the markers above the calibration plane, mm, toward the camera (default: 0); "
                        "needs a multi-view calibration unless 0")


def _add_sim_camera(p: argparse.ArgumentParser) -> None:
    p.add_argument("--camera", choices=("aalborg", "flat"), default="aalborg",
                   help="aalborg: the physically modelled camera of the paper (1280 x 1024 px of 7.4 um, f = 25 mm, "
                        "340 mm above the plane, tilt, lens distortion, vignetting, blur, noise, 8 bit; default); "
                        "flat: an ideal camera with a plain mm-per-pixel scale")
    g = p.add_argument_group("aalborg camera")
    g.add_argument("--tilt-deg", type=_nonnegative_float, default=2.0, help="tilt of the optical axis (default: 2)")
    g.add_argument("--distortion-px", type=_nonnegative_float, default=4.0,
                   help="barrel distortion at the image corner, px (default: 4)")
    g.add_argument("--falloff", type=_nonnegative_float, default=0.3,
                   help="illumination fall-off across the image, 0-0.9 (default: 0.3)")
    f = p.add_argument_group("flat camera")
    f.add_argument("--mm-per-pixel", type=_positive_float, default=None, help="scale, mm per pixel")
    f.add_argument("--size", nargs=2, type=_common.positive_int, default=None, metavar=("WIDTH", "HEIGHT"),
                   help="image size in pixels (default: 600 600)")
    f.add_argument("--blur", type=_nonnegative_float, default=1.0, help="Gaussian blur sigma in px (default: 1)")
    f.add_argument("--noise", type=_nonnegative_float, default=0.01,
                   help="standard deviation of the Gaussian noise, grey levels in [0, 1] (default: 0.01)")
    p.add_argument("--seed", type=int, default=None, help="seed of the image noise (default: random)")


def register(sub: argparse._SubParsersAction) -> None:
    vp = sub.add_parser("vision", help="vision measurement: calibrate a camera, measure the platform pose",
                        description="Camera calibration from a dot sheet and platform pose from its 2 x 2 markers "
                                    "(paper Sec. 5). Pixel coordinates are [col, row]; the mm frame is the sheet's: "
                                    "origin at the dot nearest the image centre, x along the dot rows toward "
                                    "increasing column, y up in the image.")
    vsub = vp.add_subparsers(dest="vision_command", metavar="SUBCOMMAND", parser_class=type(vp))
    vsub.required = True

    p = vsub.add_parser("calibrate", help="calibrate the camera from images of the dot sheet",
                        description="PLANE shows the sheet on the reference plane and defines the measurement frame. "
                                    "With two or more further VIEWs (the sheet moved and tilted by 10-30 deg) the "
                                    "intrinsics and lens distortion are estimated (Zhang's method, OpenCV); with "
                                    "PLANE alone, a plane homography with radial distortion is fitted (markers must "
                                    "then lie on the plane). Parts of the sheet may be outside the images.")
    p.add_argument("images", nargs="+", metavar="IMAGE", help="PLANE.png first, then the optional views")
    _add_spacing(p, "dot spacing of the sheet")
    p.add_argument("--out", required=True, metavar="CAL.toml", help="calibration file to write")
    p.add_argument("--fit-k3", action="store_true", help="also fit the sixth-order radial term k3 (multi-view)")
    p.add_argument("--max-dot-px", type=_positive_float, default=None,
                   help="largest dot diameter in px (default: 12 %% of the shorter image side)")
    _add_detection(p)
    _common.add_format(p)
    p.set_defaults(func=run_calibrate)

    p = vsub.add_parser("pose", help="platform pose x, y, phi (and its 1-sigma uncertainty) from the 2 x 2 markers",
                        description="Detect the four markers (a square of side --spacing-mm), map them onto the "
                                    "plane at --marker-height-mm and fit their position and orientation. phi is in "
                                    "(-45, 45] deg because a square repeats every quarter turn.")
    p.add_argument("image", metavar="IMAGE", help="image file showing the platform markers")
    scale = p.add_mutually_exclusive_group(required=True)
    scale.add_argument("--calibration", metavar="CAL.toml", help="calibration file from 'vision calibrate'")
    scale.add_argument("--mm-per-pixel", type=_positive_float, metavar="S",
                       help="plain scale instead of a calibration (origin at the image centre, y up)")
    _add_height(p)
    _add_spacing(p, "side of the marker square")
    _add_detection(p)
    _common.add_format(p)
    p.set_defaults(func=run_pose)

    p = vsub.add_parser("batch", help="measure the photos of a manifest and write the measurement CSV",
                        description="MANIFEST.csv has the columns image,point,x_nom,y_nom,phi_nom_deg,push (image "
                                    "paths relative to the manifest). Writes the measurement CSV that 'experiment "
                                    "compare' reads; any photo that fails stops the batch with its name.")
    p.add_argument("manifest", metavar="MANIFEST.csv", help="manifest of the photos")
    p.add_argument("--calibration", required=True, metavar="CAL.toml", help="calibration file")
    _add_height(p)
    p.add_argument("--out", required=True, metavar="MEASUREMENTS.csv", help="measurement CSV to write")
    _add_spacing(p, "side of the marker square")
    _add_detection(p)
    _common.add_format(p)
    p.set_defaults(func=run_batch)

    p = vsub.add_parser("detect", help="list the centres of the round dots in an image (pixels)",
                        description="Sub-pixel centres [col, row] of the round dots (x right, y down) and the 1-sigma "
                                    "noise of each coordinate.")
    p.add_argument("image", metavar="IMAGE", help="image file")
    _add_detection(p)
    _common.add_format(p)
    p.set_defaults(func=run_detect)

    p = vsub.add_parser("render-pose", help="write a test image of the platform markers at a known pose",
                        description="Render the 2 x 2 markers at the pose (X, Y, PHI) in the measurement frame, "
                                    "--marker-height-mm above the reference plane (seeded, reproducible).")
    p.add_argument("--x", type=_common.finite_float, default=0.0, help="x of the platform centre, mm")
    p.add_argument("--y", type=_common.finite_float, default=0.0, help="y of the platform centre, mm")
    p.add_argument("--phi-deg", type=_common.finite_float, default=0.0, help="orientation, deg")
    _add_height(p)
    _add_spacing(p, "side of the marker square")
    p.add_argument("--marker-radius-mm", type=_positive_float, default=1.5, help="marker radius (default: 1.5)")
    p.add_argument("--distractors", type=_nonnegative_int, default=0,
                   help="stray round blobs on the plane (aalborg camera; default: 0)")
    _add_sim_camera(p)
    p.add_argument("--out", required=True, metavar="IMG.png", help="image file to write")
    p.set_defaults(func=run_render_pose)

    p = vsub.add_parser("render-sheet", help="write a test image of the calibration dot sheet",
                        description="aalborg camera: view 0 is the sheet on the reference plane (its frame is the "
                                    "measurement frame), views 1, 2, ... the sheet tilted by 10-30 deg (seeded by "
                                    "--pose-seed). flat camera: the sheet at a plain scale, rotated by --rotation-deg.")
    p.add_argument("--view", type=_nonnegative_int, default=0, help="calibration view (aalborg; default: 0)")
    p.add_argument("--pose-seed", type=int, default=0, help="seed of the tilted views' poses (default: 0)")
    p.add_argument("--rotation-deg", type=_common.finite_float, default=None, help="rotation of the sheet (flat)")
    _add_spacing(p, "grid spacing")
    p.add_argument("--dot-radius-mm", type=_positive_float, default=2.0, help="dot radius (default: 2)")
    _add_sim_camera(p)
    p.add_argument("--out", required=True, metavar="IMG.png", help="image file to write")
    p.set_defaults(func=run_render_sheet)

    p = vsub.add_parser("render-batch", help="photograph the readings of a measurement CSV (aalborg camera)",
                        description="For every reading of a measurement CSV (e.g. from 'experiment simulate'), "
                                    "render the markers at that pose, --marker-height-mm above the plane, into "
                                    "OUT_DIR/<point>_<push>.png and write OUT_DIR/manifest.csv for 'vision batch'.")
    p.add_argument("--measurements", required=True, metavar="M.csv", help="measurement CSV with the true poses")
    p.add_argument("--out-dir", required=True, metavar="DIR", help="folder for the photos and manifest.csv")
    _add_height(p)
    _add_spacing(p, "side of the marker square")
    p.add_argument("--marker-radius-mm", type=_positive_float, default=1.5, help="marker radius (default: 1.5)")
    p.add_argument("--tilt-deg", type=_nonnegative_float, default=2.0, help="tilt of the optical axis (default: 2)")
    p.add_argument("--distortion-px", type=_nonnegative_float, default=4.0,
                   help="barrel distortion at the image corner, px (default: 4)")
    p.add_argument("--falloff", type=_nonnegative_float, default=0.3, help="illumination fall-off (default: 0.3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the image noise (default: 0)")
    p.set_defaults(func=run_render_batch)


# ------------------------------------------------------------------------------------------------------ helpers
def _load_calibration(path: str):
    from ..vision.calibration import Calibration

    return Calibration.from_toml(path)


def _check_out(path: str, what: str) -> Path:
    """An output path whose folder exists (checked before long computations)."""
    out = Path(path)
    if out.is_dir():
        raise PmAccuracyError(f"{out}: is a directory; give a {what} file name")
    if not out.parent.exists():
        raise PmAccuracyError(f"{out}: folder {out.parent} does not exist")
    return out


def _check_image_out(path: str) -> Path:
    from ..vision._util import IMAGE_SUFFIXES

    out = _check_out(path, "image")
    if out.suffix.lower() not in IMAGE_SUFFIXES:
        raise PmAccuracyError(f"{out}: unsupported image type {out.suffix or '(no extension)'!r}; use one of "
                              f"{', '.join(IMAGE_SUFFIXES)}")
    return out


def _sim(args: argparse.Namespace):
    from ..vision import camera_sim

    if args.falloff >= 0.9:
        raise PmAccuracyError(f"--falloff must be below 0.9, got {args.falloff:g}")
    try:
        return camera_sim.aalborg_camera(tilt_deg=args.tilt_deg, corner_distortion_px=args.distortion_px,
                                         falloff=args.falloff)
    except PmAccuracyError as exc:
        raise PmAccuracyError(f"cannot set up the camera: {exc}") from None


def _flat_only(args: argparse.Namespace, names: tuple[str, ...]) -> None:
    given = [n for n in names if getattr(args, n.replace("-", "_"), None) is not None]
    if given:
        raise PmAccuracyError(f"--{given[0]} applies to --camera flat only")


# ------------------------------------------------------------------------------------------------------ commands
def run_calibrate(args: argparse.Namespace) -> int:
    from ..vision.calibration import calibrate_views
    from ..vision.images import load_image

    out = _check_out(args.out, "calibration")
    images = [load_image(path) for path in args.images]
    cal = calibrate_views(images, names=args.images, spacing_mm=args.spacing_mm, polarity=args.polarity,
                          max_diameter_px=args.max_dot_px, fit_k3=args.fit_k3)
    try:
        cal.to_toml(out)
    except OSError as exc:
        raise PmAccuracyError(f"{out}: cannot write calibration ({exc.strerror or exc})") from None
    summary = {"model": cal.model, "n_views": cal.n_views, "n_points": cal.n_points, **cal.residuals,
               "mm_per_pixel": cal.mm_per_pixel}
    if cal.has_intrinsics:
        summary.update(focal_px=float(cal.camera.matrix[0, 0]), camera_height_mm=cal.camera_height_mm)
    summary["out"] = str(out)
    _common.emit(summary, args.format)
    return 0


def run_pose(args: argparse.Namespace) -> int:
    from ..vision.images import load_image
    from ..vision.pose import measure_pose

    calibration = _load_calibration(args.calibration) if args.calibration else None
    if calibration is not None:
        try:
            calibration.plane_at(args.marker_height_mm)
        except PmAccuracyError as exc:
            raise PmAccuracyError(f"{args.calibration}: {exc}") from None
    elif args.marker_height_mm != 0:
        raise PmAccuracyError("--marker-height-mm needs --calibration with a multi-view calibration, not a plain "
                              "--mm-per-pixel scale")
    image = load_image(args.image)
    try:
        pose = measure_pose(image, calibration=calibration, mm_per_pixel=args.mm_per_pixel,
                            height_mm=args.marker_height_mm, spacing_mm=args.spacing_mm, polarity=args.polarity)
    except PmAccuracyError as exc:
        raise PmAccuracyError(f"{args.image}: {exc}") from None
    _common.emit(pose.as_dict(), args.format)
    return 0


def run_batch(args: argparse.Namespace) -> int:
    from ..experiment import write_measurements
    from ..vision.batch import measure_batch, read_manifest

    out = _check_out(args.out, "measurement CSV")
    calibration = _load_calibration(args.calibration)
    try:
        calibration.plane_at(args.marker_height_mm)
    except PmAccuracyError as exc:
        raise PmAccuracyError(f"{args.calibration}: {exc}") from None
    rows = read_manifest(args.manifest)
    measurements, records = measure_batch(rows, calibration, height_mm=args.marker_height_mm,
                                          spacing_mm=args.spacing_mm, polarity=args.polarity)
    write_measurements(out, measurements)
    _common.emit(records, args.format)
    return 0


def run_detect(args: argparse.Namespace) -> int:
    from ..vision.detection import find_blobs
    from ..vision.images import load_image

    blobs = find_blobs(load_image(args.image), polarity=args.polarity)
    _common.emit([{"col": c, "row": r, "sigma_px": s} for (c, r), s in zip(blobs.centres, blobs.sigma_px)],
                 args.format)
    return 0


def run_render_pose(args: argparse.Namespace) -> int:
    from ..vision.images import save_image

    out = _check_image_out(args.out)
    phi = math.radians(args.phi_deg)
    if args.camera == "flat":
        from ..vision.render import render_platform

        if args.marker_height_mm != 0 or args.distractors:
            raise PmAccuracyError("--marker-height-mm and --distractors need --camera aalborg")
        width, height = args.size or (600, 600)
        image = render_platform(args.x, args.y, phi, shape=(height, width), mm_per_pixel=args.mm_per_pixel or 0.1,
                                spacing_mm=args.spacing_mm, marker_radius_mm=args.marker_radius_mm,
                                blur_sigma=args.blur, noise_sigma=args.noise, seed=args.seed)
    else:
        from ..vision import camera_sim

        _flat_only(args, ("mm-per-pixel", "size"))
        image = camera_sim.render_platform(_sim(args), args.x, args.y, phi, args.marker_height_mm,
                                           spacing_mm=args.spacing_mm, marker_radius_mm=args.marker_radius_mm,
                                           distractors=args.distractors, seed=args.seed)
    save_image(out, image)
    return 0


def run_render_sheet(args: argparse.Namespace) -> int:
    from ..vision.images import save_image

    out = _check_image_out(args.out)
    if args.camera == "flat":
        from ..vision.render import render_calibration_sheet

        if args.view:
            raise PmAccuracyError("--view needs --camera aalborg")
        width, height = args.size or (600, 600)
        sheet = render_calibration_sheet((height, width), mm_per_pixel=args.mm_per_pixel or 0.25,
                                         rotation=math.radians(args.rotation_deg or 0.0), spacing_mm=args.spacing_mm,
                                         dot_radius_mm=args.dot_radius_mm, blur_sigma=args.blur,
                                         noise_sigma=args.noise, seed=args.seed)
    else:
        from ..vision import camera_sim

        _flat_only(args, ("mm-per-pixel", "size", "rotation-deg"))
        sheet = camera_sim.render_view(_sim(args), args.view, pose_seed=args.pose_seed, seed=args.seed,
                                       spacing_mm=args.spacing_mm, dot_radius_mm=args.dot_radius_mm)
    save_image(out, sheet.image)
    return 0


def run_render_batch(args: argparse.Namespace) -> int:
    import csv

    from ..experiment import PUSHES, load_measurements
    from ..vision import camera_sim
    from ..vision.images import save_image

    folder = Path(args.out_dir)
    if folder.exists() and not folder.is_dir():
        raise PmAccuracyError(f"{folder}: exists and is not a folder")
    measurements = load_measurements(args.measurements)
    sim = _sim(args)
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    n = 0
    for k, point in enumerate(measurements.points):  # one photo per reading
        nom = measurements.nominal[k]
        for j, push in enumerate(PUSHES):
            x, y, phi = measurements.readings[k, j]
            name = f"{point}_{push.replace('+', 'p').replace('-', 'm')}.png"
            image = camera_sim.render_platform(sim, x, y, phi, args.marker_height_mm, spacing_mm=args.spacing_mm,
                                               marker_radius_mm=args.marker_radius_mm, seed=args.seed + n)
            save_image(folder / name, image)
            rows.append([name, point, repr(float(nom[0])), repr(float(nom[1])),
                         repr(float(measurements.phi_nom_deg[k])), push])
            n += 1
    with open(folder / "manifest.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(["image", "point", "x_nom", "y_nom", "phi_nom_deg", "push"])
        writer.writerows(rows)
    return 0
