"""Optional dependencies, imported where they are used and named with the extra that installs them.

The core (kinematics, bounds, maps, reports) needs numpy, scipy, matplotlib, xarray, pyarrow, tomli-w and
tqdm; the rest come with extras of ``pip install "pmaccuracy[...]"``:

=========  ====================================  ==========================================================
extra      packages                              for
=========  ====================================  ==========================================================
vision     opencv-python-headless, scikit-image  camera calibration, marker detection, rendered photos
design     cvxpy                                 minimum-cost synthesis; the semidefinite fallback of the
                                                 certified dual bound (hard cases; without it the bound
                                                 stays the interior point's, still valid)
scale      dask[array,distributed], zarr         ``--dask`` maps, Zarr maps of any size, clusters
formats    mujoco, yourdfpy                      robots read from and written to MJCF and URDF files
all        every one of the above
=========  ====================================  ==========================================================
"""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import MissingDependencyError

#: Top-level module -> (extra, the package that provides it).
EXTRAS = {
    "cv2": ("vision", "opencv-python-headless"),
    "skimage": ("vision", "scikit-image"),
    "cvxpy": ("design", "cvxpy"),
    "dask": ("scale", "dask"),
    "distributed": ("scale", "dask[distributed]"),
    "zarr": ("scale", "zarr"),
    "mujoco": ("formats", "mujoco"),
    "yourdfpy": ("formats", "yourdfpy"),
}


def require(module: str, purpose: str = "") -> ModuleType:
    """Import ``module`` (e.g. ``"skimage.filters"``) or raise :class:`MissingDependencyError` naming the extra.

    >>> require("numpy").__name__
    'numpy'
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".")[0]
        if top not in EXTRAS or (exc.name is not None and exc.name.split(".")[0] != top):
            raise
        extra, package = EXTRAS[top]
        what = f"{purpose} needs" if purpose else "this needs"
        raise MissingDependencyError(f"{what} {package}, which is not installed: pip install "
                                     f"\"pmaccuracy[{extra}]\" (or \"pmaccuracy[all]\")") from None


def available(module: str) -> bool:
    """True when ``module`` can be imported (no error raised)."""
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True
