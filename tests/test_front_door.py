"""The package's front door (``import pmaccuracy as pm``), its lazy loading, readable results, and the extras.

The numbers through the front door are compared with the modules' own functions (which the rest of the
suite checks against independent references); the missing-extra tests hide a package from ``import``.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import pmaccuracy as pm
from pmaccuracy import _optional
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError, MissingDependencyError

POSES = np.array([[0.0, 0.0, 0.0], [10.0, -5.0, 0.3]])


def test_import_is_light():
    """``import pmaccuracy`` loads no numpy, matplotlib, xarray or optional package: names load on first use."""
    code = ("import sys, pmaccuracy; heavy = [m for m in ('numpy', 'matplotlib', 'xarray', 'scipy', 'cv2', 'cvxpy',"
            " 'dask', 'zarr') if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_every_public_name_resolves_and_is_listed():
    assert len(pm.__all__) == len(set(pm.__all__))
    for name in pm.__all__:
        assert getattr(pm, name) is not None, name
    assert set(pm.__all__) <= set(dir(pm))
    for name in ("max_pose_errors", "certified_pose_errors", "global_worst", "error_map", "synthesize",
                 "pose_statistics", "load_robot", "load_clearances", "Manipulator", "ErrorSources",
                 "PmAccuracyError", "MissingDependencyError"):
        assert name in pm.__all__
    assert pm.accuracy.bounds.max_pose_errors is max_pose_errors  # submodules as attributes
    with pytest.raises(AttributeError, match="no_such_name"):
        pm.no_such_name  # noqa: B018


def test_dir_lists_only_public_names():
    """``dir(pm)`` shows what a user may call, not the package's helpers, even after submodules were imported."""
    import pmaccuracy.accuracy.global_worst  # noqa: F401 - a submodule named like a public function

    names = dir(pm)
    assert set(pm.__all__) <= set(names)
    assert not {"sys", "types", "importlib", "annotations"} & set(names)
    assert all(n == "__version__" or not n.startswith("_") for n in names), names
    for name in names:          # every listed name resolves; submodules are the package's own modules
        value = getattr(pm, name)
        assert value is not None and (not hasattr(value, "__path__") or value.__name__ == f"pmaccuracy.{name}")
    assert callable(pm.global_worst)   # the function, not the module of the same name


def test_flat_module_names_are_gone():
    """The deprecated flat aliases (``pmaccuracy.bounds`` ...) were removed: their new homes import."""
    import importlib

    for old, new in (("bounds", "accuracy.bounds"), ("geometry", "model.manipulator"), ("maps", "accuracy.maps")):
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(f"pmaccuracy.{old}")
        importlib.import_module(f"pmaccuracy.{new}")


def test_front_door_numbers_are_the_modules_numbers():
    a = pm.max_pose_errors("aalborg_3ppr", "case2", POSES)
    b = max_pose_errors(pm.Manipulator.preset("aalborg_3ppr"), pm.ClearanceSet.preset("case2"), POSES)
    for q in ("dx_max", "dy_max", "dphi_max", "dp_max"):
        np.testing.assert_array_equal(getattr(a, q), getattr(b, q))


def test_load_robot_and_clearances(tmp_path):
    robot = pm.load_robot("symmetric_3prr")
    assert robot.architecture == "3-PRR" and pm.load_robot(robot) is robot
    path = tmp_path / "mine.toml"
    robot.to_toml(path)
    assert pm.load_robot(str(path)) == robot
    assert isinstance(pm.load_robot("planar_3r_arm"), pm.SerialArm)
    assert isinstance(pm.load_clearances("prr_typical", robot), pm.ErrorSources)
    assert isinstance(pm.load_clearances("arm_typical", "planar_3r_arm"), pm.SerialErrorSources)
    with pytest.raises(ConfigError, match="expected a robot"):
        pm.load_robot(3.0)
    with pytest.raises(ConfigError, match="no_such_robot"):
        pm.load_robot("no_such_robot")


def test_results_print_readably():
    b = pm.max_pose_errors("aalborg_3ppr", "case1", POSES)
    text = repr(b)
    assert text.startswith("PoseErrorBounds(2 poses: dx_max ") and "mm" in text and "deg" in text
    assert len(text) < 300  # a summary, not the arrays
    lo, hi = float(np.min(b.dx_max)), float(np.max(b.dx_max))
    assert f"{lo:.4g}..{hi:.4g} mm" in text
    html = b._repr_html_()
    assert html.count("<tr>") == 3 and "dp_max" in html
    c = pm.certified_pose_errors("aalborg_3ppr", "case1", POSES[:1])
    assert repr(c).startswith("CertifiedPoseErrors(1 pose: dx upper ") and "gap" in repr(c)
    robot = pm.load_robot("aalborg_3ppr")
    w = pm.global_worst(robot, "case1", pm.make_region(robot, (0.0, 0.0), (-5.0, 5.0, -5.0, 5.0)))
    assert repr(w).startswith("GlobalWorst(dx ") and "<table>" in w._repr_html_()


@pytest.mark.parametrize("module,extra", [("cv2", "vision"), ("skimage.filters", "vision"), ("cvxpy", "design"),
                                          ("zarr", "scale"), ("dask.array", "scale")])
def test_missing_extra_names_the_extra(monkeypatch, module, extra):
    for name in {module.split(".")[0], module}:
        monkeypatch.setitem(sys.modules, name, None)  # as if not installed (even if imported before)
    with pytest.raises(MissingDependencyError, match=rf'pip install "pmaccuracy\[{extra}\]"'):
        _optional.require(module)
    assert not _optional.available(module)


def test_missing_extra_on_the_command_line_is_one_line(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "zarr", None)
    status = main(["map", "--robot", "aalborg_3ppr", "--clearances", "case1", "--grid", "5", "--phi-deg", "0",
                   "--out", str(tmp_path / "m.zarr")])
    err = capsys.readouterr().err.strip()
    assert status == 2 and len(err.splitlines()) == 1 and "pmaccuracy[scale]" in err


def test_certified_bound_without_cvxpy_stays_valid(monkeypatch):
    """The semidefinite fallback of the dual bound needs the design extra; without it a hard-case row keeps the
    interior point's (valid) bound instead of failing."""
    from pmaccuracy.accuracy import certified as C

    monkeypatch.setitem(sys.modules, "cvxpy", None)
    P = np.eye(2)[None] * 4.0
    out = C._sdp_dual(P, np.ones((3, 2)), np.zeros((3, 2, 2)))
    assert out.shape == (3,) and np.all(np.isinf(out))


def test_one_resolver_gives_the_same_error_for_the_same_mistake(tmp_path):
    """A robot file that cannot assemble anywhere in its ranges: every entry point refuses it the same way."""
    data = pm.load_robot("symmetric_3rpr").to_dict()
    for leg in data["legs"]:
        leg["length_range"] = [1.0, 10.0]
    path = tmp_path / "bad.toml"
    import tomli_w

    path.write_text(tomli_w.dumps(data))
    calls = [lambda: pm.load_robot(path), lambda: pm.max_pose_errors(path, "rpr_typical", POSES),
             lambda: pm.inverse_kinematics(path, POSES), lambda: pm.certified_pose_errors(path, "rpr_typical", POSES),
             lambda: pm.make_region(path, (0.0, 0.0), None), lambda: pm.load_clearances("rpr_typical", path),
             lambda: pm.error_map(path, "rpr_typical", 0.0, n=5), lambda: pm.constant_orientation_workspace(path, 0.0)]
    messages = set()
    for call in calls:
        with pytest.raises(pm.GeometryError) as info:
            call()
        messages.add(str(info.value))
    assert len(messages) == 1, messages
    assert "bad.toml" in messages.pop()
