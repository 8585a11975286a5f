"""The first call in a process does no avoidable work (issue 35), checked by what happens, not by timing.

Each check runs in a fresh interpreter, since what it looks at (the allocator's thresholds, the modules
imported) is process state that earlier tests change.
"""

from __future__ import annotations

import ctypes
import importlib.util
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"


def run_fresh(code: str) -> dict:
    """Run ``code`` in a fresh interpreter with this checkout's sources first; it prints one JSON line."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _has_mallinfo2() -> bool:
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        return hasattr(ctypes.CDLL(None), "mallinfo2")
    except OSError:
        return False


MAPPED_BLOCKS = """
import ctypes, json, sys
import numpy as np
class Info(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]
libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Info
def mapped():
    return libc.mallinfo2().hblks
from pmaccuracy.numerics.memory import settle_allocator   # (the package's imports first)
out = {}
n0 = mapped(); a = np.empty(1 << 17); out["plain"] = mapped() - n0   # a 1 MiB temporary: its own mapping
settle_allocator()
n0 = mapped(); b = np.empty(1 << 17); out["settled"] = mapped() - n0   # (a kept: its free would settle too)
print(json.dumps(out))
"""


@pytest.mark.skipif(not _has_mallinfo2(), reason="counts glibc's mapped blocks (mallinfo2)")
def test_settled_allocator_keeps_block_temporaries_on_the_heap():
    """Before: a 1 MiB array gets its own mapping (fresh pages every block); after settle_allocator: from the
    heap, where the next block finds its pages already there."""
    out = run_fresh(MAPPED_BLOCKS)
    assert out["plain"] == 1
    assert out["settled"] == 0


def test_settle_allocator_is_idempotent_and_changes_no_result():
    import numpy as np

    from pmaccuracy.accuracy.bounds import max_pose_errors
    from pmaccuracy.numerics import memory

    poses = np.array([[0.0, 0.0, 0.0], [5.0, -3.0, 0.2], [-8.0, 4.0, -0.3]])
    first = max_pose_errors("aalborg_3ppr", "case1", poses)
    memory.settle_allocator()
    assert memory._settled
    again = max_pose_errors("aalborg_3ppr", "case1", poses)
    for q in ("dx_max", "dy_max", "dphi_max", "dp_max"):
        assert np.array_equal(getattr(first, q), getattr(again, q))


NO_DASK = """
import json, sys
import numpy as np
import xarray
from pmaccuracy.accuracy.maps import error_map
ds = error_map("aalborg_3ppr", "case1", np.radians([0.0, 30.0]), n=15, progress=False)
print(json.dumps({"dask": sorted(m for m in sys.modules if m == "dask" or m.startswith("dask.")),
                  "inside": int(np.isfinite(ds.dp_max.values).sum())}))
"""


@pytest.mark.skipif(importlib.util.find_spec("dask") is None, reason="only matters with dask installed")
def test_error_map_does_not_import_dask():
    """xarray's probes for dask arrays import dask (about 0.6 s) when a Dataset is built from numpy arrays
    the ordinary way; the map's Dataset is built without them."""
    out = run_fresh(NO_DASK)
    assert out["inside"] > 0
    assert out["dask"] == []


def test_map_dataset_is_the_ordinary_dataset():
    """The Dataset built without the probes is identical (values, coordinates, indexes, attributes) to the
    one xarray builds the ordinary way from the same arrays."""
    import numpy as np
    import xarray as xr

    from pmaccuracy.accuracy.maps import MAP_VARIABLES, _coords, error_map

    phis = np.radians([0.0, 30.0])
    ds = error_map("aalborg_3ppr", "case1", phis, n=17, progress=False)
    data_vars = {name: (("phi", "y", "x"), ds[name].values.copy(), {"units": units, "long_name": long_name})
                 for name, (units, long_name) in MAP_VARIABLES.items()}
    ordinary = xr.Dataset(data_vars, coords=_coords(phis, ds.x.values.copy(), ds.y.values.copy()), attrs=ds.attrs)
    xr.testing.assert_identical(ds, ordinary)
    for name in ("phi", "y", "x"):
        assert ds.indexes[name].equals(ordinary.indexes[name])
        assert ds.indexes[name].dtype == ordinary.indexes[name].dtype == np.float64
    assert list(ds.data_vars) == list(ordinary.data_vars)
