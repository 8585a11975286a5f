"""Largest norm of a Minkowski sum of segments, discs and ellipsoids (pmaccuracy.numerics.support), checked
against independent references written here: brute force over every sign pattern (zonotopes), singular
values and closed forms, dense random sampling of the sphere, and the configuration the result returns."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmaccuracy.errors import ConfigError
from pmaccuracy.numerics.support import max_norm, support


def brute_zonotope(G: np.ndarray) -> np.ndarray:
    """``max |sum_j s_j g_j|`` over all 2^s sign patterns; ``G (N, 3, s)``."""
    s = G.shape[-1]
    signs = np.array(list(itertools.product([-1.0, 1.0], repeat=s)))
    pts = np.einsum("ps,ncs->npc", signs, G)
    return np.sqrt((pts ** 2).sum(-1)).max(axis=1)


def unit_directions(n: int, rng) -> np.ndarray:
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def sampled_max(blocks_one: list[np.ndarray], U: np.ndarray) -> float:
    """``max_u h(u)`` over the sampled unit directions, h written independently: ``sum_j |A_j^T u|``."""
    h = np.zeros(len(U))
    for A in blocks_one:
        h += np.linalg.norm(U @ A, axis=1)
    return float(h.max())


def check_point(res, blocks, tol=1e-12):
    """The returned point is ``sum_j A_j x_j`` with ``|x_j| <= 1`` and its norm is the lower bound."""
    pt = sum(np.einsum("ncd,nd->nc", np.broadcast_to(A, res.point.shape[:-1] + A.shape[-2:]), x)
             for A, x in zip(blocks, res.configuration))
    np.testing.assert_allclose(pt, res.point, rtol=0, atol=tol * (1 + np.abs(res.point).max()))
    np.testing.assert_allclose(np.linalg.norm(pt, axis=-1), res.lower, rtol=1e-12, atol=1e-300)
    for x in res.configuration:
        assert np.all(np.linalg.norm(x, axis=-1) <= 1 + 1e-12)
    np.testing.assert_allclose(np.linalg.norm(res.direction, axis=-1), 1.0, rtol=1e-12)


# ------------------------------------------------------------------------------------------ zonotopes


@pytest.mark.parametrize("s", range(1, 9))
def test_zonotope_exact_against_all_sign_patterns(s):
    rng = np.random.default_rng(s)
    G = rng.normal(size=(200, 3, s)) * rng.uniform(0.1, 3.0, size=(200, 1, s))
    blocks = [G[..., j:j + 1] for j in range(s)]
    res = max_norm(blocks)
    ref = brute_zonotope(G)
    np.testing.assert_allclose(res.upper, ref, rtol=1e-12)
    np.testing.assert_allclose(res.lower, ref, rtol=1e-12)
    assert res.exact.all() and res.certified.all()
    check_point(res, blocks)


@pytest.mark.parametrize("case", ["parallel", "coplanar", "collinear", "zero", "duplicate_planar"])
def test_zonotope_degenerate(case):
    rng = np.random.default_rng(7)
    a = rng.normal(size=(50, 3, 1))
    b = rng.normal(size=(50, 3, 1))
    c = rng.normal(size=(50, 3, 1))
    if case == "parallel":
        G = np.concatenate([a, 2.0 * a, -0.5 * a, b, c], axis=-1)
    elif case == "coplanar":
        G = np.concatenate([a, b, a + b, a - 2.0 * b, 0.3 * a + 0.7 * b], axis=-1)
    elif case == "collinear":
        G = np.concatenate([a, -3.0 * a, 0.25 * a], axis=-1)
    elif case == "zero":
        G = np.concatenate([a, np.zeros_like(a), b], axis=-1)
    else:
        G = np.concatenate([a, b, a + b, c, c, 2 * c], axis=-1)
    blocks = [G[..., j:j + 1] for j in range(G.shape[-1])]
    res = max_norm(blocks)
    np.testing.assert_allclose(res.upper, brute_zonotope(G), rtol=1e-12)
    check_point(res, blocks)


# ------------------------------------------------------------------------------------------ closed forms


@pytest.mark.parametrize("d", [2, 3])
def test_single_ellipsoid_or_disc_is_largest_singular_value(d):
    rng = np.random.default_rng(d)
    A = rng.normal(size=(300, 3, d))
    res = max_norm([A], gap=1e-6)
    sv = np.linalg.svd(A, compute_uv=False)[:, 0]
    assert np.all(res.lower <= sv * (1 + 1e-12))
    assert np.all(res.upper >= sv * (1 - 1e-12))
    assert res.certified.all()
    assert np.all(res.upper - res.lower <= 1e-6 * res.lower)
    check_point(res, [A])


def test_ball_plus_segment_closed_form():
    rng = np.random.default_rng(3)
    r = rng.uniform(0.1, 2.0, size=100)
    a = rng.uniform(0.0, 2.0, size=100)
    ball = r[:, None, None] * np.eye(3)
    seg = np.zeros((100, 3, 1))
    seg[:, 2, 0] = a
    res = max_norm([ball, seg])
    exact = r + a
    assert np.all(res.lower <= exact * (1 + 1e-12)) and np.all(res.upper >= exact * (1 - 1e-12))
    assert np.all(res.upper <= exact * (1 + 1e-3) * (1 + 1e-12))
    assert res.certified.all()


def random_rotations(rng, n):
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    return q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]


def test_balls_and_segments_exact():
    # isotropic balls r_j Q_j (any orthogonal Q_j) and segments: R = sum r_j + the zonotope's R, exactly
    rng = np.random.default_rng(8)
    n = 100
    r = rng.uniform(0.05, 0.5, size=(3, n))
    balls = [r[j][:, None, None] * random_rotations(rng, n) for j in range(3)]
    G = rng.normal(size=(n, 3, 5))
    blocks = balls + [G[..., j:j + 1] for j in range(5)]
    res = max_norm(blocks)
    exact = r.sum(0) + brute_zonotope(G)
    np.testing.assert_allclose(res.upper, exact, rtol=1e-12)
    np.testing.assert_allclose(res.lower, exact, rtol=1e-12)
    assert res.exact.all() and res.certified.all()
    check_point(res, blocks)
    # a ball made slightly anisotropic goes through the branch and bound: same R up to the gap
    squashed = [balls[0] * np.array([1.0, 1.0, 1.0 - 1e-6])] + blocks[1:]
    res2 = max_norm(squashed)
    assert not res2.exact.any() and res2.certified.all()
    assert np.all(res2.upper >= exact * (1 - 1e-5)) and np.all(res2.lower <= exact * (1 + 1e-12))
    check_point(res2, squashed)


def test_only_balls():
    res = max_norm([2.0 * np.eye(3), 0.5 * np.eye(3)[None].repeat(4, 0)])
    np.testing.assert_allclose(res.upper, 2.5, rtol=1e-14)
    np.testing.assert_allclose(res.lower, 2.5, rtol=1e-14)
    assert res.exact.all()


def test_two_orthogonal_discs():
    # disc of radius 1 in the xy-plane + disc of radius 2 in the yz-plane: R = 3 (along y)
    d1 = np.array([[[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]])
    d2 = np.array([[[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]]])
    res = max_norm([d1, d2], gap=1e-6)
    assert res.lower[0] <= 3.0 + 1e-12 <= res.upper[0] + 2e-12
    assert res.upper[0] <= 3.0 * (1 + 1e-6) + 1e-12
    check_point(res, [d1, d2])


def test_ball_plus_anything_at_least_radius_plus():
    rng = np.random.default_rng(5)
    r = 0.7
    other = [rng.normal(size=(40, 3, d)) for d in (1, 2, 3)]
    res = max_norm([r * np.eye(3)[None]] + other)
    alone = max_norm(other)
    # S = r B + S' contains x' + r x'/|x'| for the farthest x' of S': R >= r + R'
    assert np.all(res.upper >= (r + alone.lower) * (1 - 1e-12))


# ------------------------------------------------------------------------------------------ random mixes


def random_mix(rng, n, dims):
    return [rng.normal(size=(n, 3, d)) * rng.uniform(0.1, 1.0) for d in dims]


@pytest.mark.parametrize("seed,dims", [(0, (3, 3, 1, 1, 1)), (1, (2, 1, 1, 2)), (2, (3,) * 6 + (1,) * 12),
                                       (3, (2, 2, 2)), (4, (1, 3))])
def test_random_mix_against_sphere_sampling(seed, dims):
    rng = np.random.default_rng(seed)
    n = 12
    blocks = random_mix(rng, n, dims)
    res = max_norm(blocks)
    U = unit_directions(200_000, rng)
    for i in range(n):
        one = [A[i] for A in blocks]
        smax = sampled_max(one, U)
        assert res.upper[i] >= smax * (1 - 1e-12)
        # the lower bound beats dense sampling up to the sampling's resolution
        assert res.lower[i] >= smax * (1 - 1e-4)
    assert res.certified.all()
    assert np.all(res.upper - res.lower <= 1e-3 * res.lower)
    check_point(res, blocks)
    # the support function agrees with the independent h
    u = unit_directions(n, rng)
    ref = np.array([sum(np.linalg.norm(u[i] @ A[i]) for A in blocks) for i in range(n)])
    np.testing.assert_allclose(support(blocks, u), ref, rtol=1e-13)


def test_vectorized_equals_one_by_one():
    rng = np.random.default_rng(11)
    n = 10_000
    blocks = random_mix(rng, n, (3, 3, 2, 1, 1, 1, 1))
    res = max_norm(blocks)
    assert res.upper.shape == (n,) and res.point.shape == (n, 3)
    for i in rng.choice(n, size=20, replace=False):
        one = max_norm([A[i:i + 1] for A in blocks])
        # the same certified interval up to the gap (the search order may differ only in rounding)
        assert one.lower[0] <= res.upper[i] * (1 + 1e-12) and res.lower[i] <= one.upper[0] * (1 + 1e-12)
        np.testing.assert_allclose(one.lower[0], res.lower[i], rtol=1e-3)
    zres = max_norm([A for A in blocks if A.shape[-1] == 1])
    for i in rng.choice(n, size=20, replace=False):
        one = max_norm([A[i:i + 1] for A in blocks if A.shape[-1] == 1])
        np.testing.assert_allclose(one.upper[0], zres.upper[i], rtol=1e-13)


def test_broadcast_leading_shape():
    rng = np.random.default_rng(2)
    ball = np.eye(3)                         # shared by every pose
    segs = rng.normal(size=(4, 5, 3, 1))
    res = max_norm([ball, segs])
    assert res.upper.shape == (4, 5) and res.direction.shape == (4, 5, 3)
    assert res.configuration[0].shape == (4, 5, 3) and res.configuration[1].shape == (4, 5, 1)
    flat = max_norm([np.broadcast_to(ball, (20, 3, 3)), segs.reshape(20, 3, 1)])
    np.testing.assert_allclose(res.lower.ravel(), flat.lower, rtol=1e-12)


def test_uncertified_when_levels_run_out():
    rng = np.random.default_rng(4)
    blocks = random_mix(rng, 30, (3, 3, 1, 1))
    res = max_norm(blocks, gap=1e-9, max_levels=3)
    assert not res.certified.all()
    fine = max_norm(blocks, gap=1e-6)
    assert np.all(res.upper >= fine.lower * (1 - 1e-12)) and np.all(res.lower <= fine.upper * (1 + 1e-12))


def test_bad_blocks():
    with pytest.raises(ConfigError):
        max_norm([])
    with pytest.raises(ConfigError):
        max_norm([np.ones((2, 3, 4))])
    with pytest.raises(ConfigError):
        max_norm([np.full((2, 3, 1), np.nan)])


def test_zero_set():
    res = max_norm([np.zeros((3, 3, 3)), np.zeros((3, 3, 1))])
    assert np.all(res.upper == 0) and np.all(res.lower == 0) and res.certified.all()


# ------------------------------------------------------------------------------------------ properties

_dims = st.lists(st.sampled_from([1, 2, 3]), min_size=1, max_size=5)


@settings(max_examples=30, deadline=None)
@given(dims=_dims, seed=st.integers(0, 2**31), c=st.floats(0.01, 100.0))
def test_scaling_scales_r(dims, seed, c):
    rng = np.random.default_rng(seed)
    blocks = random_mix(rng, 3, dims)
    a = max_norm(blocks)
    b = max_norm([c * A for A in blocks])
    # both certified intervals contain R and c R respectively
    assert np.all(b.upper >= c * a.lower * (1 - 1e-12)) and np.all(c * a.upper >= b.lower * (1 - 1e-12))


@settings(max_examples=30, deadline=None)
@given(dims=_dims, extra=st.sampled_from([1, 2, 3]), seed=st.integers(0, 2**31))
def test_adding_a_block_never_decreases_r(dims, extra, seed):
    rng = np.random.default_rng(seed)
    blocks = random_mix(rng, 3, dims)
    a = max_norm(blocks)
    b = max_norm(blocks + random_mix(rng, 3, (extra,)))
    assert np.all(b.upper >= a.lower * (1 - 1e-12))


@settings(max_examples=60, deadline=None)
@given(G=st.lists(st.tuples(*[st.integers(-2, 2)] * 3), min_size=1, max_size=7))
def test_zonotope_small_integer_generators_exact(G):
    # small integer generators: many parallel, coplanar and zero generators, exact ties everywhere
    A = np.array(G, dtype=float).T[None]                      # (1, 3, s)
    res = max_norm([A[..., j:j + 1] for j in range(A.shape[-1])])
    ref = brute_zonotope(A)
    np.testing.assert_allclose(res.upper, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res.lower, ref, rtol=1e-12, atol=1e-12)


def test_many_live_cells_split_between_poses(monkeypatch):
    # a nearly round set keeps most cells alive: the refinement splits them between poses (bounded memory)
    import pmaccuracy.numerics.support as support_module

    rng = np.random.default_rng(12)
    n = 40
    blocks = [np.eye(3) * np.array([1.0, 1.0, 1.0 - 1e-4]), 0.01 * rng.normal(size=(n, 3, 1))]
    whole = max_norm(blocks)
    monkeypatch.setattr(support_module, "_MAX_CELLS", 64)
    split = max_norm(blocks)
    assert whole.certified.all() and split.certified.all()
    assert np.all(split.upper >= whole.lower * (1 - 1e-12)) and np.all(whole.upper >= split.lower * (1 - 1e-12))
    check_point(split, blocks)
