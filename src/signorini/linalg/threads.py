"""How many threads the dense BLAS may use inside the time loop.

A step works on small dense blocks (the Delassus matrix of the candidate contact
nodes, the product with the active columns of Z = K^-1 B^T, vectors).  A threaded
BLAS wakes its threads for each of these calls; on a small machine the threads cost
more than they save, and next to MKL's own threads (Pardiso) the two pools compete:
hertz3d n = 9 with Pardiso on 2 cores takes 128 ms per step with OpenBLAS's default
threads and 49 ms with one (docs/performance.md).  :func:`blas_threads` limits the
OpenBLAS and BLIS pools for the duration of a ``with`` block through threadpoolctl;
MKL is left alone, since its threads also run Pardiso's solves, which gain from them.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from typing import Any


@contextmanager
def blas_threads(n: int, controller: Any = None) -> Iterator[None]:
    """Limit the BLAS libraries loaded in the process to ``n`` threads inside the block
    (``n = 0``: leave them as they are).  ``controller``: one made by :func:`blas_controller`
    before (finding the loaded libraries costs about a millisecond: a stepper driven step by
    step makes it once); None: made here."""
    if n <= 0:
        with nullcontext():
            yield
        return
    with (controller if controller is not None else blas_controller()).limit(limits=n):
        yield


def blas_controller() -> Any:
    """The OpenBLAS and BLIS libraries loaded in the process now, for :func:`blas_threads`
    (by library, not by API: MKL is also Pardiso's solver, whose threads pay off)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController().select(internal_api=["openblas", "blis"])
