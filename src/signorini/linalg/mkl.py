"""MKL's runtime library (``mkl_rt``), as loaded by pypardiso (the extra ``pardiso``).

One copy of MKL per process: the library object pypardiso opened is reused, so the
sparse BLAS products (:mod:`.spmv`) and Pardiso (:mod:`.pardiso`) share MKL's
threads.  The calls use MKL's LP64 interface (32-bit integers), MKL's default; a
process that sets ``MKL_INTERFACE_LAYER=ILP64`` is refused.
"""

from __future__ import annotations

import ctypes
import functools
import os


@functools.cache
def mkl_runtime() -> ctypes.CDLL | None:
    """The ``mkl_rt`` library pypardiso loaded, or None (pypardiso missing, or an MKL
    whose integers are not 32-bit)."""
    if os.environ.get("MKL_INTERFACE_LAYER", "LP64").upper().startswith("ILP64"):
        return None
    try:
        import pypardiso
    except (ImportError, OSError):
        return None
    lib = getattr(getattr(pypardiso, "ps", None), "libmkl", None)
    if lib is None or not hasattr(lib, "mkl_sparse_d_mv"):
        return None
    return lib


def has_mkl() -> bool:
    """Whether MKL's runtime (with its sparse BLAS) is available."""
    return mkl_runtime() is not None
