"""Nodal contact frames (contact/frames.py): orthonormal, right-handed, smooth in the normal."""

import numpy as np
import pytest

from signorini.contact.frames import frame_rows, tangent_frames


@pytest.mark.parametrize("dim", [2, 3])
def test_frames_are_orthonormal_and_right_handed(dim):
    n = np.random.default_rng(0).normal(size=(500, dim))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    F = np.concatenate([n[:, None, :], tangent_frames(n)], axis=1)  # rows: nu, t_1 (, t_2)
    assert np.abs(np.einsum("iab,icb->iac", F, F) - np.eye(dim)).max() <= 1e-15
    assert np.abs(np.linalg.det(F) - 1.0).max() <= 1e-15


def test_2d_frames_rotate_with_the_normal():
    a = 0.7
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    n = np.array([[0.0, -1.0], [0.6, 0.8]])
    assert np.abs(tangent_frames(n @ R.T)[:, 0] - tangent_frames(n)[:, 0] @ R.T).max() <= 1e-15


def test_3d_frames_are_smooth_away_from_horizontal_normals():
    """Two normals 1e-6 apart (nu_z > 0): their tangents are 1e-6 apart too."""
    n = np.array([[0.3, -0.2, 0.9]])
    m = n + 1e-6 * np.array([[1.0, 0.5, -0.2]])
    n, m = (v / np.linalg.norm(v) for v in (n, m))
    assert np.abs(tangent_frames(n) - tangent_frames(m)).max() <= 1e-5


def test_frame_rows_put_each_vector_on_its_node_dofs():
    dofs = np.array([[2, 3], [6, 7]])
    vectors = np.array([[[1.0, 2.0]], [[3.0, 4.0]]])
    H = frame_rows(dofs, vectors, 8).toarray()
    expected = np.zeros((2, 8))
    expected[0, [2, 3]] = [1.0, 2.0]
    expected[1, [6, 7]] = [3.0, 4.0]
    assert np.array_equal(H, expected)
    assert tangent_frames(np.ones((3, 1))).shape == (3, 0, 1)  # 1D: no tangent
