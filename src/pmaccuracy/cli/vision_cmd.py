"""``pmaccuracy vision ...``: camera calibration, platform pose from photos, batches, test images (paper Sec. 5).

Sub-commands:

* ``calibrate PLANE.png [VIEW.png ...] --out CAL.toml`` - fit the camera (Zhang with >= 3 images, else a plane
  homography with radial distortion);
* ``pose IMAGE (--calibration CAL.toml | --mm-per-pixel S) [--marker-height-mm H]`` - pose of the 2 x 2 markers,
  with its 1-sigma uncertainty;
* ``batch MANIFEST.csv --calibration CAL.toml --out MEASUREMENTS.csv`` - photos -> measurement CSV; a
  calibration manifest (command columns, no ``push``; ``--calibration`` or ``--mm-per-pixel``) -> the
  calibration CSV of ``calibrate identify``;
* ``detect IMAGE`` - list the detected dot centres in pixels;
* ``render-sheet`` / ``render-pose`` / ``render-batch`` - seeded test images from the physically modelled camera
  (or the flat one).

Heavy libraries (OpenCV, SciPy, scikit-image) are imported inside the command functions.
"""

from __future__ import annotations

import argparse
import functools
import math
import re
import warnings
from pathlib import Path

from ..errors import PmAccuracyError
from . import _common

DEFAULT_SPACING_MM = 20.0  # the paper's sheet and marker square (pmaccuracy.vision.DEFAULT_SPACING_MM)
#: Plain scale of the flat test camera, mm per pixel, for both the sheet and the platform images (so that a
#: calibration of render-sheet --camera flat measures render-pose --camera flat).
FLAT_MM_PER_PIXEL = 0.25
#: Limits of the options of the simulated cameras (documented in each --help).
MAX_TILT_DEG = 30.0
MAX_DISTORTION_PX = 50.0
MAX_FALLOFF = 0.9
MAX_BLUR_PX = 20.0
MAX_DISTRACTORS = 100
#: Smallest marker / dot radius in the image (px) that the detector finds (area >= 12 px^2), and the most
#: sheet dots one image may hold (rendering cost).
MIN_RADIUS_PX = 2.0
MAX_SHEET_DOTS = 2000
#: Clearance kept between a marker's outline and the image border, px (the detector drops cut blobs).
BORDER_PX = 4.0
#: Plausible ranges (warnings outside, not errors): marker height, mm; sheet / square spacing, mm; scale, mm/px.
PLAUSIBLE_HEIGHT_MM = (0.0, 100.0)
PLAUSIBLE_SPACING_MM = (1.0, 200.0)
PLAUSIBLE_MM_PER_PIXEL = (1e-3, 10.0)
OUT_POLICY = getattr(_common, "FOLDER_POLICY", "missing parent folders are created")


def _warn(message: str) -> None:
    """A plausibility warning: one line ``pmaccuracy vision: warning: ...`` on stderr (silenced by --quiet)."""
    warnings.warn(message, _plausibility_warning(), stacklevel=2)


def _ranged_float(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
                  hi_open: bool = False):
    """argparse type: a finite number in [lo, hi] (open ends where asked); the message states the range."""
    def parse(text: str) -> float:
        value = _common.finite_float(text)
        below = lo is not None and (value <= lo if lo_open else value < lo)
        above = hi is not None and (value >= hi if hi_open else value > hi)
        if below or above:
            left = "(" if lo_open else "["
            right = ")" if hi_open else "]"
            span = f"{left}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}{right}"
            raise argparse.ArgumentTypeError(f"must be in {span}, got {text!r}")
        return value
    return parse


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


_nonnegative_int = _common.nonnegative_int


def _max_dot(text: str) -> float:
    """argparse type: a dot diameter in px above 2."""
    value = _common.finite_float(text)
    if value <= 2:
        raise argparse.ArgumentTypeError(f"must be above 2 px: {text!r}")
    return value


def _distractors(text: str) -> int:
    value = _nonnegative_int(text)
    if value > MAX_DISTRACTORS:
        raise argparse.ArgumentTypeError(f"at most {MAX_DISTRACTORS}: {text!r}")
    return value


def _add_detection(p: argparse.ArgumentParser) -> None:
    p.add_argument("--polarity", choices=("dark", "light"), default="dark",
                   help="dark dots on a light background (default) or light dots on a dark one")


def _add_spacing(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--spacing-mm", type=_positive_float, default=DEFAULT_SPACING_MM,
                   help=f"{what} in mm (default: {DEFAULT_SPACING_MM:g}; a warning outside "
                        f"{PLAUSIBLE_SPACING_MM[0]:g}-{PLAUSIBLE_SPACING_MM[1]:g})")


def _add_height(p: argparse.ArgumentParser) -> None:
    p.add_argument("--marker-height-mm", type=_common.finite_float, default=0.0, metavar="H",
                   help="height of the markers above the calibration plane, mm, toward the camera (default: 0; "
                        "must be below the camera; a warning outside "
                        f"{PLAUSIBLE_HEIGHT_MM[0]:g}-{PLAUSIBLE_HEIGHT_MM[1]:g}); needs a multi-view calibration "
                        "unless 0")


def _add_seed(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--seed", type=_nonnegative_int, default=0,
                   help=f"seed of the {what}, a whole number >= 0 (default: 0; the same seed gives the same image)")


def _add_aalborg_options(g) -> None:
    g.add_argument("--tilt-deg", type=_ranged_float(0.0, MAX_TILT_DEG), default=2.0,
                   help=f"tilt of the optical axis, 0-{MAX_TILT_DEG:g} (default: 2)")
    g.add_argument("--distortion-px", type=_ranged_float(0.0, MAX_DISTORTION_PX), default=4.0,
                   help=f"barrel distortion at the image corner, px, 0-{MAX_DISTORTION_PX:g} (default: 4)")
    g.add_argument("--falloff", type=_ranged_float(0.0, MAX_FALLOFF, hi_open=True), default=0.3,
                   help=f"illumination fall-off across the image, 0 to below {MAX_FALLOFF:g} (default: 0.3)")


def _add_sim_camera(p: argparse.ArgumentParser) -> None:
    from ..vision.images import MAX_IMAGE_PIXELS

    p.add_argument("--camera", choices=("aalborg", "flat"), default="aalborg",
                   help="aalborg: the physically modelled camera of the paper (1280 x 1024 px of 7.4 um, f = 25 mm, "
                        "340 mm above the plane, tilt, lens distortion, vignetting, blur, noise, 8 bit; default); "
                        "flat: an ideal camera with a plain mm-per-pixel scale")
    _add_aalborg_options(p.add_argument_group("aalborg camera"))
    f = p.add_argument_group("flat camera")
    f.add_argument("--mm-per-pixel", type=_positive_float, default=None,
                   help=f"scale, mm per pixel (default: {FLAT_MM_PER_PIXEL:g})")
    f.add_argument("--size", nargs=2, type=_common.positive_int, default=None, metavar=("WIDTH", "HEIGHT"),
                   help=f"image size in pixels, each side >= 16, at most {MAX_IMAGE_PIXELS:,} pixels "
                        "(default: 600 600)")
    f.add_argument("--blur", type=_ranged_float(0.0, MAX_BLUR_PX), default=1.0,
                   help=f"Gaussian blur sigma in px, 0-{MAX_BLUR_PX:g} (default: 1)")
    f.add_argument("--noise", type=_ranged_float(0.0, 1.0), default=0.01,
                   help="standard deviation of the Gaussian noise, grey levels in [0, 1] (default: 0.01)")
    _add_seed(p, "image noise")


def _image_out(p: argparse.ArgumentParser) -> None:
    from ..vision._util import IMAGE_SUFFIXES

    p.add_argument("--out", required=True, metavar="IMG.png",
                   help=f"image file to write ({', '.join(IMAGE_SUFFIXES)}; PNG and TIFF keep 16 bits); "
                        f"{OUT_POLICY}")


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
    p.add_argument("--out", required=True, metavar="CAL.toml", help=f"calibration file to write; {OUT_POLICY}")
    p.add_argument("--fit-k3", action="store_true", help="also fit the sixth-order radial term k3 (multi-view)")
    p.add_argument("--max-dot-px", type=_max_dot, default=None,
                   help="largest dot diameter in px, above 2 and at most half the shorter image side (default: "
                        "12 %% of the shorter image side)")
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

    p = vsub.add_parser("batch", help="measure the photos of a manifest and write the measurement CSV (or the "
                                      "calibration CSV of a calibration manifest)",
                        description="MANIFEST.csv has the columns image,point,x_nom,y_nom,phi_nom_deg,push (image "
                                    "paths relative to the manifest): writes the measurement CSV that 'experiment "
                                    "compare' reads (needs --calibration). A calibration manifest (image,point, the "
                                    "command columns q1 or q1_deg, ..., x_nom,y_nom,phi_nom_deg; written by "
                                    "'calibrate simulate --photos'): writes the calibration CSV (point, the "
                                    "commands, x,y,phi_deg and the photos' sigma_x,sigma_y,sigma_phi_deg) that "
                                    "'calibrate identify --data' reads. Any photo that fails stops the batch with "
                                    "its name.")
    p.add_argument("manifest", metavar="MANIFEST.csv", help="manifest of the photos")
    scale = p.add_mutually_exclusive_group(required=True)
    scale.add_argument("--calibration", metavar="CAL.toml", help="calibration file")
    scale.add_argument("--mm-per-pixel", type=_positive_float, metavar="S",
                       help="plain scale instead of a calibration (origin at the image centre, y up; the flat "
                            "camera of 'calibrate simulate --photos', default there 0.25); calibration manifests "
                            "only")
    _add_height(p)
    p.add_argument("--out", required=True, metavar="MEASUREMENTS.csv",
                   help=f"measurement CSV to write; {OUT_POLICY}")
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
    p.add_argument("--phi-deg", type=_common.angle_deg, default=0.0, help="orientation, deg")
    _add_height(p)
    _add_spacing(p, "side of the marker square")
    p.add_argument("--marker-radius-mm", type=_positive_float, default=1.5,
                   help="marker radius, below half the spacing (default: 1.5)")
    p.add_argument("--distractors", type=_distractors, default=0,
                   help=f"stray round blobs on the plane (aalborg camera; 0-{MAX_DISTRACTORS}; default: 0)")
    _add_sim_camera(p)
    _image_out(p)
    p.set_defaults(func=run_render_pose)

    p = vsub.add_parser("render-sheet", help="write a test image of the calibration dot sheet",
                        description="aalborg camera: view 0 is the sheet on the reference plane (its frame is the "
                                    "measurement frame), views 1, 2, ... the sheet tilted by 10-30 deg (seeded by "
                                    "--pose-seed). flat camera: the sheet at a plain scale, rotated by --rotation-deg.")
    p.add_argument("--view", type=_nonnegative_int, default=0, help="calibration view (aalborg; default: 0)")
    p.add_argument("--pose-seed", type=_nonnegative_int, default=0,
                   help="seed of the tilted views' poses, >= 0 (default: 0)")
    p.add_argument("--rotation-deg", type=_common.finite_float, default=None, help="rotation of the sheet (flat)")
    _add_spacing(p, "grid spacing")
    p.add_argument("--dot-radius-mm", type=_positive_float, default=2.0,
                   help="dot radius, below 0.4 x the spacing (default: 2)")
    _add_sim_camera(p)
    _image_out(p)
    p.set_defaults(func=run_render_sheet)

    p = vsub.add_parser("render-batch", help="photograph the readings of a measurement CSV (aalborg camera)",
                        description="For every reading of a measurement CSV (e.g. from 'experiment simulate'), "
                                    "render the markers at that pose, --marker-height-mm above the plane, into "
                                    "OUT_DIR/<point>_<push>.png and write OUT_DIR/manifest.csv for 'vision batch'.")
    p.add_argument("--measurements", required=True, metavar="M.csv", help="measurement CSV with the true poses")
    p.add_argument("--out-dir", required=True, metavar="DIR",
                   help="folder for the photos and manifest.csv (created if missing)")
    _add_height(p)
    _add_spacing(p, "side of the marker square")
    p.add_argument("--marker-radius-mm", type=_positive_float, default=1.5,
                   help="marker radius, below half the spacing (default: 1.5)")
    _add_aalborg_options(p)
    _add_seed(p, "first photo's noise (photo k uses SEED + k)")
    p.set_defaults(func=run_render_batch)


# ------------------------------------------------------------------------------------------------------ helpers
def _plausibility_warning() -> type[Warning]:
    try:
        from ..model.plausibility import PlausibilityWarning
    except ImportError:  # pragma: no cover - older tree
        return UserWarning
    return PlausibilityWarning


def _vision_command(func):
    """Run a command with numpy's floating-point warnings off (every result is checked for finiteness instead).

    Plausibility warnings raised on the way are printed (one line each, unless
    ``--quiet``) when the command succeeds; when it fails they are appended to
    its one error line as a note, so that stderr holds exactly one line.
    """
    @functools.wraps(func)
    def run(args: argparse.Namespace) -> int:
        import numpy as np

        kind = _plausibility_warning()
        quiet = bool(getattr(args, "quiet", False))
        with warnings.catch_warnings(record=True) as caught, np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            warnings.simplefilter("always", kind)
            try:
                status = func(args)
            except MemoryError:
                error: PmAccuracyError | None = PmAccuracyError(
                    "out of memory (images above the pixel limit are refused; see --help)")
            except PmAccuracyError as exc:
                error = exc
            else:
                error = None
        notes = [str(w.message) for w in caught if issubclass(w.category, kind)]
        if error is not None:
            if notes and not quiet:
                raise PmAccuracyError(f"{error} (note: {'; '.join(notes)})") from None
            raise error
        for w in caught:  # re-issued outside: the CLI prints them one line each, or not at all with --quiet
            if not quiet:
                warnings.warn(w.message, w.category, stacklevel=2)
        return status
    return run


def _load_calibration(path: str):
    from ..vision.calibration import Calibration

    return Calibration.from_toml(path)


def _output(path: str, option: str = "--out", kinds=None, *, folder: bool = False) -> Path:
    """An output path checked before any work; missing parent folders are created (``_common.prepare_output``)."""
    return _common.prepare_output(path, option, kinds, folder=folder)


def _image_output(path: str) -> Path:
    from ..vision._util import IMAGE_SUFFIXES

    return _output(path, "--out", IMAGE_SUFFIXES)


def _save(path: Path, image, option: str = "--out") -> None:
    from ..vision.images import save_image

    try:
        save_image(path, image)
    except OSError as exc:
        raise PmAccuracyError(f"{path}: {option}: cannot write the image ({exc.strerror or exc})") from None


def _check_height(args: argparse.Namespace, calibration=None, source: str | None = None) -> None:
    """``--marker-height-mm``: below the camera (an error naming the option), plausible (a warning), usable
    with the calibration (single-view: 0 only)."""
    h = args.marker_height_mm
    lo, hi = PLAUSIBLE_HEIGHT_MM
    if h < lo:
        _warn(f"--marker-height-mm {h:g} puts the markers below the reference plane (expected {lo:g}-{hi:g} mm above "
              "it)")
    elif h > hi:
        _warn(f"--marker-height-mm {h:g} is above {hi:g} mm (markers are usually a few mm above the sheet; is it "
              "in um?)")
    if calibration is None:
        return
    camera_height = calibration.camera_height_mm
    if camera_height is not None and h >= 0.95 * camera_height:
        raise PmAccuracyError(f"--marker-height-mm {h:g}: the markers would be at or above the camera, "
                              f"{camera_height:.4g} mm above the plane ({source})")
    try:
        calibration.plane_at(h)
    except PmAccuracyError as exc:
        raise PmAccuracyError(f"{source}: {exc}") from None


def _check_spacing(value: float, option: str = "--spacing-mm") -> None:
    lo, hi = PLAUSIBLE_SPACING_MM
    if not lo <= value <= hi:
        _warn(f"{option} {value:g} is outside {lo:g}-{hi:g} mm (the paper's sheet and marker square: 20 mm; "
              "wrong unit?)")


def _check_scale(value: float | None, option: str = "--mm-per-pixel") -> None:
    lo, hi = PLAUSIBLE_MM_PER_PIXEL
    if value is not None and not lo <= value <= hi:
        _warn(f"{option} {value:g} is outside {lo:g}-{hi:g} mm per pixel (wrong unit?)")


def _sim(args: argparse.Namespace):
    from ..vision import camera_sim

    try:
        return camera_sim.aalborg_camera(tilt_deg=args.tilt_deg, corner_distortion_px=args.distortion_px,
                                         falloff=args.falloff)
    except PmAccuracyError as exc:
        raise PmAccuracyError(f"cannot set up the camera with --tilt-deg {args.tilt_deg:g} --distortion-px "
                              f"{args.distortion_px:g} --falloff {args.falloff:g}: {exc}") from None


def _flat_only(args: argparse.Namespace, names: tuple[str, ...]) -> None:
    given = [n for n in names if getattr(args, n.replace("-", "_"), None) is not None]
    if given:
        raise PmAccuracyError(f"--{given[0]} applies to --camera flat only")


def _flat_shape(args: argparse.Namespace) -> tuple[int, int]:
    """``(height, width)`` of a flat image from ``--size`` (each side >= 16, at most the pixel limit)."""
    from ..vision.images import MAX_IMAGE_PIXELS

    width, height = args.size or (600, 600)
    if min(width, height) < 16:
        raise PmAccuracyError(f"--size {width} {height}: each side must be at least 16 pixels")
    if width * height > MAX_IMAGE_PIXELS:
        raise PmAccuracyError(f"--size {width} {height}: {width * height:,} pixels is above the limit of "
                              f"{MAX_IMAGE_PIXELS:,}")
    return height, width


def _circles(centres, radius: float, n: int = 16):
    """Points ``(len(centres) * n, 2)`` on circles of ``radius`` around ``centres`` ``(N, 2)``."""
    import numpy as np

    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    ring = radius * np.stack([np.cos(t), np.sin(t)], axis=1)
    return (np.asarray(centres, dtype=float)[:, None, :] + ring).reshape(-1, 2)


def _markers_fit(outline_px, size: tuple[int, int], radius_px: float, what: str) -> None:
    """Refuse markers whose outline ``(M, 2)`` px leaves the image (``size`` = width, height) or that are too small
    to detect. ``what`` names the options / reading in the message."""
    import numpy as np

    w, h = size
    pts = np.asarray(outline_px, dtype=float)
    inside = np.all(np.isfinite(pts)) and np.all((pts >= BORDER_PX) & (pts <= np.array([w - 1, h - 1]) - BORDER_PX))
    if not inside:
        raise PmAccuracyError(f"{what}: the markers would not lie wholly inside the {w} x {h} px image "
                              f"(keep them {BORDER_PX:g} px from the border)")
    if not radius_px >= MIN_RADIUS_PX:
        raise PmAccuracyError(f"{what}: the markers would be {radius_px:.3g} px in radius, below the "
                              f"{MIN_RADIUS_PX:g} px the detector needs")


def _aalborg_marker_check(sim, x: float, y: float, phi: float, height: float, spacing: float, radius: float,
                          what: str) -> None:
    """Markers of the pose on the simulated camera's image (before rendering), else an error naming ``what``."""
    import numpy as np

    from ..vision._util import apply_homography
    from ..vision.pose import platform_markers

    camera_height = float(-sim.rotation[:, 2] @ sim.translation)
    if height >= 0.95 * camera_height:
        raise PmAccuracyError(f"--marker-height-mm {height:g}: the markers would be at or above the camera, "
                              f"{camera_height:.4g} mm above the plane")
    centres = platform_markers(x, y, phi, spacing)
    ring = _circles(centres, radius)
    m = sim.plane(height)
    hom = np.concatenate([ring, np.ones((len(ring), 1))], axis=1) @ m.T
    if not np.all(hom[:, 2] > 0):  # behind the camera
        _markers_fit(np.full((1, 2), np.nan), sim.camera.image_size, 0.0, what)
    px = sim.project(ring, height)
    try:  # the lens model folds far-off points back into the frame: the round trip must hold
        back = sim.camera.undistort(px)
        folded = not np.allclose(back, apply_homography(m, ring), atol=1e-6)
    except PmAccuracyError:
        folded = True
    if folded:
        px = np.full_like(px, np.nan)
    centre_px = sim.project(centres, height)
    radius_px = float(np.min(np.linalg.norm(px.reshape(4, -1, 2) - centre_px[:, None, :], axis=2)))
    _markers_fit(px, sim.camera.image_size, radius_px, what)


def _radius_vs_spacing(radius: float, spacing: float, option: str, share: float) -> None:
    if radius >= share * spacing:
        raise PmAccuracyError(f"{option} {radius:g}: must be below {share:g} x --spacing-mm = {share * spacing:g} mm "
                              "(neighbouring disks would touch)")


def _pose_what(args: argparse.Namespace) -> str:
    return (f"--x {args.x:g} --y {args.y:g} --phi-deg {args.phi_deg:g} --marker-height-mm {args.marker_height_mm:g}"
            f" --spacing-mm {args.spacing_mm:g} --marker-radius-mm {args.marker_radius_mm:g}")


def _finite(record: dict, source: str) -> dict:
    """``record`` if every number in it (nested) is finite, else an error naming ``source`` and the first key."""
    def bad(value, key: str) -> str | None:
        if isinstance(value, dict):
            for k2, v in value.items():
                found = bad(v, f"{key}.{k2}" if key else k2)
                if found is not None:
                    return found
            return None
        if isinstance(value, float) and not math.isfinite(value):
            return key
        return None

    key = bad(record, "")
    if key is not None:
        raise PmAccuracyError(f"{source}: the result {key} is not finite (degenerate image or calibration)")
    return record


# ------------------------------------------------------------------------------------------------------ commands
@_vision_command
def run_calibrate(args: argparse.Namespace) -> int:
    from ..vision.calibration import calibrate_views
    from ..vision.detection import MAX_DIAMETER_LIMIT
    from ..vision.images import load_image

    out = _output(args.out)
    _check_spacing(args.spacing_mm)
    images = [load_image(path) for path in args.images]
    if args.max_dot_px is not None:
        for path, image in zip(args.images, images):
            if args.max_dot_px > MAX_DIAMETER_LIMIT * min(image.shape):
                raise PmAccuracyError(f"--max-dot-px {args.max_dot_px:g}: more than half the shorter side of "
                                      f"{path} ({min(image.shape)} px)")
    try:
        cal = calibrate_views(images, names=args.images, spacing_mm=args.spacing_mm, polarity=args.polarity,
                              max_diameter_px=args.max_dot_px, fit_k3=args.fit_k3)
    except PmAccuracyError as exc:
        if any(str(exc).startswith(f"{name}:") for name in args.images):
            raise
        raise PmAccuracyError(f"{', '.join(args.images)}: {exc}") from None
    summary = {"model": cal.model, "n_views": cal.n_views, "n_points": cal.n_points, **cal.residuals,
               "mm_per_pixel": cal.mm_per_pixel}
    if cal.has_intrinsics:
        summary.update(focal_px=float(cal.camera.matrix[0, 0]), camera_height_mm=cal.camera_height_mm)
    _finite(summary, f"calibration from {args.images[0]}")
    try:
        cal.to_toml(out)
    except OSError as exc:
        raise PmAccuracyError(f"{out}: cannot write calibration ({exc.strerror or exc})") from None
    summary["out"] = str(out)
    _common.emit(summary, args.format)
    return 0


@_vision_command
def run_pose(args: argparse.Namespace) -> int:
    from ..vision.images import load_image
    from ..vision.pose import measure_pose

    _check_spacing(args.spacing_mm)
    _check_scale(args.mm_per_pixel)
    calibration = _load_calibration(args.calibration) if args.calibration else None
    if calibration is None and args.marker_height_mm != 0:
        raise PmAccuracyError("--marker-height-mm needs --calibration with a multi-view calibration, not a plain "
                              "--mm-per-pixel scale")
    _check_height(args, calibration, args.calibration)
    image = load_image(args.image)
    try:
        pose = measure_pose(image, calibration=calibration, mm_per_pixel=args.mm_per_pixel,
                            height_mm=args.marker_height_mm, spacing_mm=args.spacing_mm, polarity=args.polarity)
    except PmAccuracyError as exc:
        raise PmAccuracyError(f"{args.image}: {exc}") from None
    _common.emit(_finite(pose.as_dict(), args.image), args.format)
    return 0


@_vision_command
def run_batch(args: argparse.Namespace) -> int:
    from ..experiment import write_measurements
    from ..vision.batch import measure_batch, read_manifest

    out = _output(args.out)
    _check_spacing(args.spacing_mm)
    _check_scale(args.mm_per_pixel)
    if _is_calibration_manifest(args.manifest):
        return _run_calibration_batch(args, out)
    rows = read_manifest(args.manifest)   # a missing or unreadable manifest is named before any option is blamed
    if args.calibration is None:
        raise PmAccuracyError("--mm-per-pixel: the clearance experiment's manifest (image,point,x_nom,y_nom,"
                              "phi_nom_deg,push) needs --calibration CAL.toml")
    calibration = _load_calibration(args.calibration)
    _check_height(args, calibration, args.calibration)
    measurements, records = measure_batch(rows, calibration, height_mm=args.marker_height_mm,
                                          spacing_mm=args.spacing_mm, polarity=args.polarity)
    for record in records:
        _finite(record, record["image"])
    write_measurements(out, measurements)
    _common.emit(records, args.format)
    return 0


def _is_calibration_manifest(path: str) -> bool:
    """Whether the manifest's header is a calibration manifest's (an unreadable file: False, and the clearance
    manifest's reader names the problem)."""
    import csv

    from ..vision.calibration_photos import is_calibration_manifest

    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            header = next(csv.reader(fh), [])
    except (OSError, UnicodeDecodeError, csv.Error):
        return False
    return is_calibration_manifest(header)


def _run_calibration_batch(args: argparse.Namespace, out) -> int:
    """``vision batch`` of a calibration manifest: the calibration CSV of ``calibrate identify``."""
    from ..vision.calibration_photos import measure_calibration_manifest, write_calibration_readings

    calibration = _load_calibration(args.calibration) if args.calibration else None
    if calibration is None and args.marker_height_mm != 0:
        raise PmAccuracyError("--marker-height-mm needs --calibration with a multi-view calibration, not a plain "
                              "--mm-per-pixel scale")
    _check_height(args, calibration, args.calibration)
    commands, records = measure_calibration_manifest(args.manifest, calibration=calibration,
                                                     mm_per_pixel=args.mm_per_pixel, height_mm=args.marker_height_mm,
                                                     spacing_mm=args.spacing_mm, polarity=args.polarity)
    for record in records:
        _finite(record, record["image"])
    try:
        write_calibration_readings(out, commands, records)
    except OSError as exc:
        raise PmAccuracyError(f"{out}: --out: cannot write ({exc.strerror or exc})") from None
    _common.emit(records, args.format)
    return 0


@_vision_command
def run_detect(args: argparse.Namespace) -> int:
    from ..vision.detection import find_blobs
    from ..vision.images import load_image

    image = load_image(args.image)
    try:
        blobs = find_blobs(image, polarity=args.polarity)
    except PmAccuracyError as exc:
        raise PmAccuracyError(f"{args.image}: {exc}") from None
    records = [{"col": c, "row": r, "sigma_px": s} for (c, r), s in zip(blobs.centres, blobs.sigma_px)]
    for record in records:
        _finite(record, args.image)
    if not records and args.format != "json":  # no dots: the header alone
        print(("," if args.format == "csv" else "  ").join(("col", "row", "sigma_px")))
        return 0
    _common.emit(records, args.format)
    return 0


@_vision_command
def run_render_pose(args: argparse.Namespace) -> int:
    out = _image_output(args.out)
    _check_spacing(args.spacing_mm)
    _check_height(args)
    _radius_vs_spacing(args.marker_radius_mm, args.spacing_mm, "--marker-radius-mm", 0.5)
    phi = math.radians(args.phi_deg)
    if args.camera == "flat":
        from ..vision._util import mm_to_pixels
        from ..vision.pose import platform_markers
        from ..vision.render import render_platform

        if args.marker_height_mm != 0 or args.distractors:
            raise PmAccuracyError("--marker-height-mm and --distractors need --camera aalborg")
        height, width = _flat_shape(args)
        scale = args.mm_per_pixel or FLAT_MM_PER_PIXEL
        _check_scale(scale)
        ring = _circles(platform_markers(args.x, args.y, phi, args.spacing_mm), args.marker_radius_mm)
        _markers_fit(mm_to_pixels(ring, scale, (height, width)), (width, height), args.marker_radius_mm / scale,
                     _pose_what(args) + f" --mm-per-pixel {scale:g}")
        image = render_platform(args.x, args.y, phi, shape=(height, width), mm_per_pixel=scale,
                                spacing_mm=args.spacing_mm, marker_radius_mm=args.marker_radius_mm,
                                blur_sigma=args.blur, noise_sigma=args.noise, seed=args.seed)
    else:
        from ..vision import camera_sim

        _flat_only(args, ("mm-per-pixel", "size"))
        sim = _sim(args)
        _aalborg_marker_check(sim, args.x, args.y, phi, args.marker_height_mm, args.spacing_mm,
                              args.marker_radius_mm, _pose_what(args))
        image = camera_sim.render_platform(sim, args.x, args.y, phi, args.marker_height_mm,
                                           spacing_mm=args.spacing_mm, marker_radius_mm=args.marker_radius_mm,
                                           distractors=args.distractors, seed=args.seed)
    _save(out, image)
    return 0


def _sheet_density(spacing_px: float, radius_px: float, pixels: int, args: argparse.Namespace, scale: str) -> None:
    """Refuse sheets whose dots are too small to detect or too many to render (options named)."""
    what = f"--spacing-mm {args.spacing_mm:g} --dot-radius-mm {args.dot_radius_mm:g}{scale}"
    if not radius_px >= MIN_RADIUS_PX:
        raise PmAccuracyError(f"{what}: the dots would be {radius_px:.3g} px in radius, below the {MIN_RADIUS_PX:g} "
                              "px the detector needs")
    dots = pixels / spacing_px**2
    if dots > MAX_SHEET_DOTS:
        raise PmAccuracyError(f"{what}: about {dots:.0f} dots would fit in the image, more than {MAX_SHEET_DOTS}")


@_vision_command
def run_render_sheet(args: argparse.Namespace) -> int:
    import numpy as np

    from ..vision._util import MIN_CALIBRATION_DOTS
    out = _image_output(args.out)
    _check_spacing(args.spacing_mm)
    _radius_vs_spacing(args.dot_radius_mm, args.spacing_mm, "--dot-radius-mm", 0.4)
    if args.camera == "flat":
        from ..vision.render import render_calibration_sheet

        if args.view:
            raise PmAccuracyError("--view needs --camera aalborg")
        height, width = _flat_shape(args)
        scale = args.mm_per_pixel or FLAT_MM_PER_PIXEL
        _check_scale(scale)
        _sheet_density(args.spacing_mm / scale, args.dot_radius_mm / scale, width * height, args,
                       f" --mm-per-pixel {scale:g}")
        sheet = render_calibration_sheet((height, width), mm_per_pixel=scale,
                                         rotation=math.radians(args.rotation_deg or 0.0), spacing_mm=args.spacing_mm,
                                         dot_radius_mm=args.dot_radius_mm, blur_sigma=args.blur,
                                         noise_sigma=args.noise, seed=args.seed)
        drawn = len(sheet.centres_mm)
        image = sheet.image
    else:
        from ..vision import camera_sim

        _flat_only(args, ("mm-per-pixel", "size", "rotation-deg"))
        sim = _sim(args)
        w, h = sim.camera.image_size
        centre = sim.project(np.zeros((1, 2)))[0]
        step = float(np.linalg.norm(sim.project(np.array([[1.0, 0.0]]))[0] - centre))  # px per mm at the origin
        _sheet_density(args.spacing_mm * step, args.dot_radius_mm * step, w * h, args, "")
        sheet = camera_sim.render_view(sim, args.view, pose_seed=args.pose_seed, seed=args.seed,
                                       spacing_mm=args.spacing_mm, dot_radius_mm=args.dot_radius_mm)
        px = np.asarray(sheet.centres_px)
        drawn = int(np.count_nonzero(np.all((px >= 0) & (px <= np.array([w - 1, h - 1])), axis=1)))
        image = sheet.image
    if drawn < MIN_CALIBRATION_DOTS:
        raise PmAccuracyError(f"--spacing-mm {args.spacing_mm:g}: only {drawn} dot(s) of the sheet in the image, a "
                              f"calibration needs {MIN_CALIBRATION_DOTS}")
    _save(out, image)
    return 0


@_vision_command
def run_render_batch(args: argparse.Namespace) -> int:
    import csv

    from ..experiment import PUSHES, load_measurements
    from ..vision import camera_sim

    folder = _output(args.out_dir, "--out-dir", folder=True)
    _check_spacing(args.spacing_mm)
    _check_height(args)
    _radius_vs_spacing(args.marker_radius_mm, args.spacing_mm, "--marker-radius-mm", 0.5)
    measurements = load_measurements(args.measurements)
    sim = _sim(args)
    lines = getattr(measurements, "lines", None)
    for k, point in enumerate(measurements.points):  # every reading checked before any photo is written
        for j, push in enumerate(PUSHES):
            x, y, phi = measurements.readings[k, j]
            line = f" (line {int(lines[k, j])})" if lines is not None and int(lines[k, j]) > 0 else ""
            _aalborg_marker_check(sim, x, y, phi, args.marker_height_mm, args.spacing_mm, args.marker_radius_mm,
                                  f"{args.measurements}: point {point} push {push}{line}")
    rows = []
    used: set[str] = set()
    n = 0
    for k, point in enumerate(measurements.points):  # one photo per reading
        nom = measurements.nominal[k]
        for j, push in enumerate(PUSHES):
            x, y, phi = measurements.readings[k, j]
            name = f"{re.sub(r'[^A-Za-z0-9_.-]', '_', str(point))}_{push.replace('+', 'p').replace('-', 'm')}.png"
            if name in used:  # two labels that differ only in characters a file name cannot hold
                name = f"{n}_{name}"
            used.add(name)
            image = camera_sim.render_platform(sim, x, y, phi, args.marker_height_mm, spacing_mm=args.spacing_mm,
                                               marker_radius_mm=args.marker_radius_mm, seed=args.seed + n)
            _save(folder / name, image, "--out-dir")
            rows.append([name, point, repr(float(nom[0])), repr(float(nom[1])),
                         repr(float(measurements.phi_nom_deg[k])), push])
            n += 1
    try:
        with open(folder / "manifest.csv", "w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(["image", "point", "x_nom", "y_nom", "phi_nom_deg", "push"])
            writer.writerows(rows)
    except OSError as exc:
        raise PmAccuracyError(f"{folder / 'manifest.csv'}: --out-dir: cannot write ({exc.strerror or exc})") from None
    return 0
