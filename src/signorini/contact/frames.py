"""Nodal contact frames: the outward normal nu_i and d - 1 orthonormal tangents t_ik.

The frame of a contact node is built from its normal alone, by a rule that is smooth
in the normal (so that frames of neighbouring nodes on a curved boundary are close and
a rotation of the whole problem rotates the frames with it in 2D):

* 2D: t = (-nu_y, nu_x), the normal turned by +90 degrees (the body's bottom normal
  ``(0, -1)`` gives ``(1, 0)``), so that (nu, t) is right-handed as in 3D;
* 3D: the branch-free orthonormal basis of Duff et al. (J. Comput. Graph. Tech. 6(1),
  2017): with s = sign(nu_z) (+1 at 0), a = -1/(s + nu_z), b = nu_x nu_y a,
  t_1 = (1 + s nu_x^2 a, s b, -s nu_x), t_2 = (b, s + nu_y^2 a, -nu_y); it is
  continuous everywhere except across nu_z = 0 where s flips (a horizontal normal),
  which is why the frame of a node is computed once, at t = 0.

The normals are those of t = 0 (:mod:`signorini.contact.obstacles`: B does not change
during a run), so the frames are constant in time, hence continuous in time, for fixed
and moving obstacles alike.  The motion of a moving obstacle enters the tangential
slip through the displacement over the step of its material point that faced the node at
t = 0 (:meth:`~signorini.contact.contact_set.ContactSet.obstacle_slip`: its translation,
and with a rotation (R(t1) - R(t0))(X_i - c), :mod:`signorini.contact.obstacles`).

A contact pair's row (:mod:`signorini.contact.pairs`) has the frame of its slave node's
nu_s = -n_m, and its rows act on the master facet's nodes too: the slip is relative to
the master surface (:func:`frame_rows` with coefficients).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def tangent_frames(normals: np.ndarray) -> np.ndarray:
    """Unit tangents (nc, d - 1, d) orthogonal to the unit ``normals`` (nc, d) and to each other.

    1D has no tangent: the result has shape (nc, 0, 1).
    """
    n = np.asarray(normals, dtype=float)
    nc, d = n.shape
    if d == 1:
        return np.zeros((nc, 0, 1))
    if d == 2:
        return np.stack([-n[:, 1], n[:, 0]], axis=1)[:, None, :]
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    s = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    t1 = np.stack([1.0 + s * x * x * a, s * b, -s * x], axis=1)
    t2 = np.stack([b, s + y * y * a, -y], axis=1)
    return np.stack([t1, t2], axis=1)


def frame_rows(
    dofs: np.ndarray, vectors: np.ndarray, n_dofs: int, coefficients: np.ndarray | None = None
) -> sp.csr_matrix:
    """The sparse matrix (nc k, n_dofs) whose row i k + j is ``vectors[i, j]`` on the dofs of node i.

    ``dofs`` (nc, d) are the dofs of the contact nodes; ``vectors`` (nc, k, d) the k
    vectors of each node's frame (its normal, its tangents or all of them), node-major.

    A row may act on several nodes (a contact pair's row: the slave node and the master
    facet's nodes, :mod:`~signorini.contact.pairs`): ``dofs`` (nc, m, d) then holds the
    dofs of the m nodes of each row (-1: no node, padding) and ``coefficients`` (nc, m)
    their coefficients c_ir, and row i k + j is

        sum_r c_ir vectors[i, j]^T u_r        (u_r: the displacement of node r of row i)

    e.g. c_i = (1, -N_1(xi), ..., -N_nfv(xi)) for the relative motion t^T u_s - sum_r N_r t^T u_r
    of a slave node against the master point it faces.  A row of one node with c = 1 gives
    the same values as the (nc, d) form.
    """
    nc, k, d = vectors.shape
    if dofs.ndim == 2:
        rows = np.repeat(np.arange(nc * k), d)
        cols = np.repeat(dofs, k, axis=0).ravel() if k else np.zeros(0, dtype=np.intp)
        return sp.csr_matrix((vectors.ravel(), (rows, cols)), shape=(nc * k, n_dofs))
    vals = coefficients[:, None, :, None] * vectors[:, :, None, :]  # (nc, k, m, d)
    rows = np.broadcast_to(np.arange(nc * k).reshape(nc, k, 1, 1), vals.shape)
    cols = np.broadcast_to(dofs[:, None, :, :], vals.shape)
    keep = cols >= 0  # padding (a row of fewer nodes) dropped; zero coefficients are kept
    return sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(nc * k, n_dofs))
