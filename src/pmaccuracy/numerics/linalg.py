"""Small dense linear algebra on batches: 3x3 inverses by cofactors."""

from __future__ import annotations

import numpy as np


def inverse_3x3(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and determinant of a batch of 3x3 matrices ``(..., 3, 3)`` by cofactors.

    Unlike ``np.linalg.inv`` it never raises: an exactly singular matrix gives
    non-finite entries, which the callers refuse.
    """
    a, b, c = M[..., 0, 0], M[..., 0, 1], M[..., 0, 2]
    d, e, f = M[..., 1, 0], M[..., 1, 1], M[..., 1, 2]
    g, h, i = M[..., 2, 0], M[..., 2, 1], M[..., 2, 2]
    cof = np.stack([
        np.stack([e * i - f * h, c * h - b * i, b * f - c * e], axis=-1),
        np.stack([f * g - d * i, a * i - c * g, c * d - a * f], axis=-1),
        np.stack([d * h - e * g, b * g - a * h, a * e - b * d], axis=-1),
    ], axis=-2)
    det = a * cof[..., 0, 0] + b * cof[..., 1, 0] + c * cof[..., 2, 0]
    # A determinant at rounding level relative to the rows' sizes (e.g. rank 1, where the cofactors are
    # noise too) is an exact singularity: make it 0 so the inverse is non-finite rather than plausible.
    row_norms = np.prod(np.linalg.norm(M, axis=-1), axis=-1)
    det = np.where(np.abs(det) <= 1e-13 * row_norms, 0.0, det)
    with np.errstate(divide="ignore", invalid="ignore"):
        return cof / det[..., None, None], det
