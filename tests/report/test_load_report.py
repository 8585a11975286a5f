"""Report section "Clearances under load" (issue 24, deliverable 6), against independent computations:

- a push's first-order reading is the support point of the error set in the push's direction: the brute-force
  maximum of ``W . dX`` over the 8 sign vertices ``dX = G t`` of the error parallelepiped (its generators ``G``
  from ``max_pose_errors(details=True)``); the ±x and ±y half-spans of case 1 at phi = 0 fall in the paper's
  simulated ranges (Sec. 6.1: dx_max 0.196-0.256 mm over the workspace, dy_max 0.100 mm);
- the preload keeps the loaded error constant: on a dense sample of the process box, ``loaded_pose_error``
  with the preload added gives one value (the reported offset) and without it spans the reported range.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.loads import Load, loaded_pose_error
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.report import PAPER_SIMULATED
from pmaccuracy.report.document import Document
from pmaccuracy.report.figures import Renderer
from pmaccuracy.report.load_report import PROCESS_BOX, PUSH_N, load_section

ROBOT = Manipulator.preset("aalborg_3ppr")
SIGNS = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))


@pytest.fixture(scope="module")
def section(tmp_path_factory):
    out = tmp_path_factory.mktemp("loads")
    doc, results = Document("t"), {}
    with Renderer(0) as renderer:
        load_section(doc, ROBOT, out, results, renderer, paper=PAPER_SIMULATED)
    return out, doc, results["loads"]


def test_pushes_are_the_support_points_of_the_error_set(section):
    _, _, data = section
    home = np.array([*data["home"], 0.0])
    for key, pushes in data["pushes"].items():
        case, phi = key.split("/")
        pose = home + [0.0, 0.0, np.radians(float(phi))]
        G = max_pose_errors(ROBOT, case, pose[None], details=True).generators[0]
        vertices = SIGNS @ G.T                                   # (8, 3) [mm, mm, rad]
        for push, W in (("+x", [PUSH_N, 0, 0]), ("-x", [-PUSH_N, 0, 0]), ("+y", [0, PUSH_N, 0]),
                        ("-y", [0, -PUSH_N, 0])):
            reading = np.array([pushes[push]["dx"], pushes[push]["dy"], np.radians(pushes[push]["dphi_deg"])])
            assert np.dot(W, reading) == pytest.approx(np.max(vertices @ W), rel=1e-9), (key, push)
        assert pushes["half_span_dx"] == pytest.approx(np.max(vertices[:, 0]), rel=1e-9)
        assert pushes["half_span_dy"] == pytest.approx(np.max(vertices[:, 1]), rel=1e-9)
    paper = data["pushes"]["case1/0"]
    assert 0.196 <= paper["half_span_dx"] <= 0.256
    assert paper["half_span_dy"] == pytest.approx(0.100, rel=0.01)


def test_preload_makes_the_error_a_constant_offset_on_a_dense_sample_of_the_box(section):
    _, _, data = section
    pre = data["preload"]
    pose = np.array([*data["home"], 0.0])
    center, half = (np.array(v) for v in PROCESS_BOX)
    grid = np.linspace(-1.0, 1.0, 5)
    sample = np.array(list(itertools.product(grid, grid, grid))) * half + center
    P = np.array(pre["wrench"])
    held, free = [], []
    for W in sample:
        held.append(loaded_pose_error(ROBOT, pre["case"], pose, Load(*(W + P)), exact=False).first_order)
        free.append(loaded_pose_error(ROBOT, pre["case"], pose, Load(*W), threshold=0.0, exact=False).first_order)
    held, free = np.array(held), np.array(free)
    offset = np.array(pre["offset"]) * [1.0, 1.0, np.pi / 180]
    np.testing.assert_allclose(held, np.broadcast_to(offset, held.shape), rtol=0, atol=1e-12)
    spread = (free.max(axis=0) - free.min(axis=0)) * [1.0, 1.0, 180 / np.pi]
    reported = np.array(pre["range_without"])
    assert np.all(spread <= reported * (1 + 1e-9)) and np.all(spread >= 0.999 * reported)
    assert pre["flipping_legs"] == [1, 2, 3]     # a box symmetric about 0 holds W and -W: every reaction flips
    assert np.all(np.abs(offset) <= np.array(pre["worst"]) * [1.0, 1.0, np.pi / 180] * (1 + 1e-9))


def test_section_is_numbered_with_its_tables_and_figures(section):
    out, doc, _ = section
    html = doc.to_html()
    assert "1. Clearances under load" in html
    assert "Figure 1. The +y push" in html and "Figure 2. The preload" in html
    for name in ("load_push_y.png", "load_preload.png"):
        assert (out / name).read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert "half the push spread" in html and "constant offset with the preload" in html
    md = doc.to_markdown()
    paper_rows = [ln for ln in md.splitlines() if "case1 | 0 | d" in ln and "pushes" in ln]
    assert len(paper_rows) == 2 and all(ln.rstrip(" |").endswith("PASS") for ln in paper_rows), paper_rows
