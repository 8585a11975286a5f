"""``pmaccuracy vision ...``: camera calibration, platform pose from an image, synthetic test images (paper Sec. 5).

Sub-commands:

* ``calibrate IMAGE --out CAL.toml`` - fit pixel -> mm on an image of a dot sheet;
* ``pose IMAGE (--calibration CAL.toml | --mm-per-pixel S)`` - pose of the 2 x 2 platform markers;
* ``detect IMAGE`` - list the detected marker centres in pixels;
* ``render-pose`` / ``render-sheet`` - write synthetic images with known ground truth.
"""

from __future__ import annotations

import argparse
import math

from .. import vision
from ..errors import PmAccuracyError
from . import _common


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


def _add_detection(p: argparse.ArgumentParser) -> None:
    p.add_argument("--polarity", choices=("dark", "light"), default="dark",
                   help="dark dots on a light background (default) or light dots on a dark one")


def _add_spacing(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--spacing-mm", type=_positive_float, default=vision.DEFAULT_SPACING_MM,
                   help=f"{what} in mm (default: {vision.DEFAULT_SPACING_MM:g})")


def _add_size(p: argparse.ArgumentParser, default: tuple[int, int]) -> None:
    p.add_argument("--size", nargs=2, type=_common.positive_int, default=list(default), metavar=("WIDTH", "HEIGHT"),
                   help=f"image size in pixels (default: {default[0]} {default[1]})")


def _add_noise(p: argparse.ArgumentParser) -> None:
    p.add_argument("--blur", type=_nonnegative_float, default=1.0, help="Gaussian blur sigma in px (default: 1)")
    p.add_argument("--noise", type=_nonnegative_float, default=0.01,
                   help="standard deviation of the Gaussian noise, grey levels in [0, 1] (default: 0.01)")
    p.add_argument("--seed", type=int, default=None, help="seed of the noise (default: random)")


def register(sub: argparse._SubParsersAction) -> None:
    vp = sub.add_parser("vision", help="vision measurement: calibrate a camera, measure the platform pose",
                        description="Camera calibration from a dot sheet and platform pose from its 2 x 2 markers "
                                    "(paper Sec. 5). Pixel coordinates are [col, row]; the mm frame has y up.")
    vsub = vp.add_subparsers(dest="vision_command", metavar="SUBCOMMAND", parser_class=type(vp))
    vsub.required = True

    p = vsub.add_parser("calibrate", help="fit pixel -> mm from an image of a calibration dot sheet",
                        description="Detect the dots of a calibration sheet, assign them to the square grid and fit "
                                    "a homography pixel -> mm. The frame's origin is the dot nearest the image "
                                    "centre, x the grid direction closest to the image's x, y up in the image.")
    p.add_argument("image", metavar="IMAGE", help="image file of the calibration sheet")
    _add_spacing(p, "grid spacing of the sheet")
    p.add_argument("--out", required=True, metavar="CAL.toml", help="calibration file to write")
    _add_detection(p)
    _common.add_format(p)
    p.set_defaults(func=run_calibrate)

    p = vsub.add_parser("pose", help="platform pose x, y, phi from the 2 x 2 markers in an image",
                        description="Detect exactly four markers (a square of side --spacing-mm) and fit their "
                                    "position and orientation. phi is in (-45, 45] deg because a square repeats "
                                    "every quarter turn.")
    p.add_argument("image", metavar="IMAGE", help="image file showing the platform markers")
    scale = p.add_mutually_exclusive_group(required=True)
    scale.add_argument("--calibration", metavar="CAL.toml", help="calibration file from 'vision calibrate'")
    scale.add_argument("--mm-per-pixel", type=_positive_float, metavar="S",
                       help="plain scale instead of a calibration (origin at the image centre, y up)")
    _add_spacing(p, "side of the marker square")
    _add_detection(p)
    _common.add_format(p)
    p.set_defaults(func=run_pose)

    p = vsub.add_parser("detect", help="list the centres of the circular markers in an image (pixels)",
                        description="Sub-pixel centres [col, row] of the circular dots (x right, y down).")
    p.add_argument("image", metavar="IMAGE", help="image file")
    _add_detection(p)
    _common.add_format(p)
    p.set_defaults(func=run_detect)

    p = vsub.add_parser("render-pose", help="write a synthetic image of the platform markers at a known pose",
                        description="Render the 2 x 2 markers for the pose (X, Y, PHI) seen at a plain scale.")
    p.add_argument("--x", type=_common.finite_float, default=0.0, help="x of the platform centre, mm")
    p.add_argument("--y", type=_common.finite_float, default=0.0, help="y of the platform centre, mm")
    p.add_argument("--phi-deg", type=_common.finite_float, default=0.0, help="orientation, deg")
    p.add_argument("--mm-per-pixel", type=_positive_float, default=0.1, help="scale, mm per pixel (default: 0.1)")
    _add_spacing(p, "side of the marker square")
    p.add_argument("--marker-radius-mm", type=_positive_float, default=1.5, help="marker radius (default: 1.5)")
    _add_size(p, (600, 600))
    _add_noise(p)
    p.add_argument("--out", required=True, metavar="IMG.png", help="image file to write")
    p.set_defaults(func=run_render_pose)

    p = vsub.add_parser("render-sheet", help="write a synthetic image of a calibration dot sheet",
                        description="Render a sheet of dots on a square grid seen at a plain scale, rotated by "
                                    "--rotation-deg.")
    p.add_argument("--mm-per-pixel", type=_positive_float, default=0.25, help="scale, mm per pixel (default: 0.25)")
    p.add_argument("--rotation-deg", type=_common.finite_float, default=0.0, help="rotation of the sheet, deg")
    _add_spacing(p, "grid spacing")
    p.add_argument("--dot-radius-mm", type=_positive_float, default=2.0, help="dot radius (default: 2)")
    _add_size(p, (600, 600))
    _add_noise(p)
    p.add_argument("--out", required=True, metavar="IMG.png", help="image file to write")
    p.set_defaults(func=run_render_sheet)


def run_calibrate(args: argparse.Namespace) -> int:
    image = vision.load_image(args.image)
    cal = vision.calibrate(image, spacing_mm=args.spacing_mm, polarity=args.polarity)
    try:
        cal.to_toml(args.out)
    except OSError as exc:
        raise PmAccuracyError(f"{args.out}: cannot write calibration ({exc.strerror or exc})") from None
    _common.emit({"n_points": cal.n_points, "residual_mm": cal.residual_mm, "mm_per_pixel": cal.mm_per_pixel,
                  "out": args.out}, args.format)
    return 0


def run_pose(args: argparse.Namespace) -> int:
    calibration = vision.Calibration.from_toml(args.calibration) if args.calibration else None
    image = vision.load_image(args.image)
    centres = vision.detect_markers(image, polarity=args.polarity)
    if len(centres) == 0:
        raise PmAccuracyError(f"{args.image}: no markers found (expected {vision.PLATFORM_MARKERS})")
    pose = vision.pose_from_markers(centres, calibration=calibration, mm_per_pixel=args.mm_per_pixel,
                                    image_shape=image.shape, spacing_mm=args.spacing_mm)
    _common.emit(pose.as_dict(), args.format)
    return 0


def run_detect(args: argparse.Namespace) -> int:
    image = vision.load_image(args.image)
    centres = vision.detect_markers(image, polarity=args.polarity)
    _common.emit([{"col": c, "row": r} for c, r in centres], args.format)
    return 0


def run_render_pose(args: argparse.Namespace) -> int:
    width, height = args.size
    image = vision.render_platform(args.x, args.y, math.radians(args.phi_deg), shape=(height, width),
                                   mm_per_pixel=args.mm_per_pixel, spacing_mm=args.spacing_mm,
                                   marker_radius_mm=args.marker_radius_mm, blur_sigma=args.blur,
                                   noise_sigma=args.noise, seed=args.seed)
    vision.save_image(args.out, image)
    return 0


def run_render_sheet(args: argparse.Namespace) -> int:
    width, height = args.size
    sheet = vision.render_calibration_sheet((height, width), mm_per_pixel=args.mm_per_pixel,
                                            rotation=math.radians(args.rotation_deg), spacing_mm=args.spacing_mm,
                                            dot_radius_mm=args.dot_radius_mm, blur_sigma=args.blur,
                                            noise_sigma=args.noise, seed=args.seed)
    vision.save_image(args.out, sheet.image)
    return 0
