"""Checkpoints: everything the next step of a run needs, in one HDF5 file, written atomically.

A checkpoint of level n holds

* the state: t_n, U, V, A, lambda, lambda_t and the scheme's declared data
  (:attr:`~.schemes.base.Scheme.state_fields`);
* the contact solvers' warm starts (:attr:`~signorini.contact.solver.ContactSolver.warm_state`:
  the previous active set, the friction multipliers of the previous step, CG's last
  solution), the pairing of the contact pairs after small sliding, the run's counters;
* the built-in observers' series for the levels 0..n (history, energies and the terms of
  their identity, the untagged watch, the events, in-memory snapshots), so that the resumed
  run's result holds every level from t = 0;
* the problem's identity (:func:`identity`): figures of the mesh, the mass and stiffness
  matrices, the contact rows and gaps, the loads and the initial state at t = 0, the
  scheme, the mass variant and dt (T excepted), and, from the command line, a hash of the
  case file.  A resume compares them and names what differs;
* a checksum of every array (a corrupt file is refused) and the format version.

The file is written to a temporary name beside it, flushed to the disk and renamed over
the previous checkpoint (``os.replace``): a kill during the write leaves the previous one.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import InputError
from ...fem.material import cell_models
from ..model.problem import friction_summary
from ..schemes.base import COMMON_STATE_FIELDS, STATE_FIELD_KINDS, State

FORMAT = "signorini-checkpoint"
#: the version this code writes and the newest it reads
VERSION = 1
#: relative tolerance of the numeric identity figures (a run on another backend or number of
#: ranks sums them in another order)
IDENTITY_RTOL = 1e-9


# ----------------------------------------------------------------------------- identity
def _weights(n: int) -> np.ndarray:
    """Fixed, well spread test weights 1 + sin(k) / 2 (k = 0 .. n - 1)."""
    return 1.0 + 0.5 * np.sin(np.arange(n, dtype=float))


def _figures(x: np.ndarray) -> list[float]:
    """Three numbers that change when a vector changes: sum |x|, sum w x, max |x| (compared to
    a relative tolerance of the largest of them: a sum near zero is round-off)."""
    x = np.asarray(x, dtype=float).ravel()
    return [float(np.abs(x).sum()), float(_weights(x.size) @ x), float(np.abs(x).max(initial=0.0))]


def identity(run, case_hash: str | None = None) -> dict[str, Any]:
    """What makes a checkpoint belong to a run: names and numbers, compared on resume.

    Numbers (figures of vectors: sum, weighted sum and largest entry) are compared to a
    relative :data:`IDENTITY_RTOL` of their scale; names exactly.
    """
    ctx, disc = run.ctx, run.ctx.disc
    mesh = disc.problem.mesh
    pts = mesh.points if mesh.node_ids is None else mesh.points[np.argsort(mesh.node_ids)]
    n = disc.space.n_dofs
    w = _weights(n)
    out = {
        "problem": str(disc.problem.name),
        "scheme": run.scheme.label,
        "mass": str(disc.mass_name),
        "dofs": int(n),
        "contact_rows": int(disc.contact.size),
        "mesh": [int(mesh.n_nodes), int(mesh.n_cells), *_figures(pts)],
        "mass_matrix": _figures(ctx.Mop @ w),
        "stiffness": _figures(ctx.Sop @ w),
        "contact": _figures(np.concatenate([ctx.gaps(0.0), ctx.rows.B @ w])),  # at set-up: before any re-pairing
        "loads": _figures(ctx.load(0.0)),
        "initial_state": _figures(np.concatenate([disc.U0, disc.V0])),
        "fixed_dofs": int(ctx.fixed.size),
        # the run's node numbering (a distributed run may renumber the mesh): the state's vectors are in it
        "node_order": "mesh" if mesh.node_ids is None else _figures(mesh.node_ids.astype(float)),
        "friction": json.dumps(friction_summary(disc.problem), sort_keys=True, default=str),
    }
    if ctx.damping is not None:  # (an undamped run's identity is the one before damping existed)
        out["damping"] = json.dumps(ctx.damping.describe(), sort_keys=True)
        if ctx.damping_matrix is not None:  # per region: which cells, not only the coefficients per tag
            out["damping_matrix"] = _figures(ctx.damping_matrix @ w)
    if ctx.elastic.finite:  # (a linear run's identity is the one before finite strain; K(0) = S hides the model)
        models = cell_models(disc.material, mesh.n_cells)
        out["material_model"] = [*ctx.elastic.models, *_figures(np.unique(models, return_inverse=True)[1] + 1.0)]
    if case_hash is not None:
        out["case_file"] = case_hash
    source = _scheme_source_hash(run.scheme)
    if source is not None:
        out["scheme_source"] = source
    return out


def _scheme_source_hash(scheme) -> str | None:
    """sha256 of the source file of a scheme of the user's own (None for a registered one): a
    resume that names a changed file (same name and options, other code) is refused."""
    import inspect

    from ..schemes import SCHEMES

    cls = type(scheme)
    try:
        if SCHEMES.get(scheme.name).obj is cls:
            return None
    except InputError:
        pass
    try:
        path = inspect.getsourcefile(cls)
        return hashlib.sha256(Path(path).read_bytes()).hexdigest() if path else None
    except (OSError, TypeError):
        return None


def compare_identity(saved: dict[str, Any], mine: dict[str, Any], where: str) -> None:
    """InputError naming the first item of the identity that differs."""
    names = {
        "case_file": "the case file (its text changed since the checkpoint)",
        "mass_matrix": "the mass matrix",
        "contact": "the contact rows or gaps",
        "initial_state": "the initial state",
        "loads": "the loads",
        "mesh": "the mesh",
        "stiffness": "the stiffness (materials)",
        "dofs": "the number of dofs",
        "contact_rows": "the number of contact rows",
        "fixed_dofs": "the Dirichlet dofs",
        "friction": "the friction law or its coefficients",
        "damping": "the damping ([material] damping: absent on one side, or other coefficients)",
        "material_model": "the material model ([material] model: linear on one side, or other models)",
        "scheme_source": "the source file of the scheme of your own (its code changed since the checkpoint)",
        "node_order": "the node numbering (a distributed backend renumbers the mesh: resume on the same "
        "kind of backend, or give solver option node_order=mesh to both)",
    }
    order = (
        "case_file",
        "problem",
        "scheme",
        "scheme_source",
        "mass",
        "node_order",
        "friction",
        "damping",
        "material_model",
        "dofs",
        "mesh",
        "contact_rows",
        "fixed_dofs",
        "stiffness",
        "mass_matrix",
        "contact",
        "loads",
        "initial_state",
    )  # the most telling difference first
    for key in sorted(set(saved) | set(mine), key=lambda k: (order.index(k) if k in order else len(order), k)):
        a, b = saved.get(key), mine.get(key)
        if (a is None or b is None) and key not in ("damping", "material_model"):  # (none: undamped, linear)
            if key in ("case_file", "scheme_source"):
                continue  # a checkpoint of the Python API resumed from a case file, or the reverse
            raise InputError(f"{where}: the checkpoint does not match this run: {key} is missing on one side")
        same = a == b
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            nums = [abs(float(v)) for v in a + b if not isinstance(v, str)]
            scale = max(nums, default=0.0)
            same = all(_close(x, y, scale) for x, y in zip(a, b, strict=True))
        elif isinstance(a, float) and isinstance(b, float):
            same = a == b if key == "dt" else _close(a, b)
        if not same:
            what = names.get(key, key)
            shown = "" if isinstance(a, list) else f" (checkpoint: {a!r}, this run: {b!r})"
            raise InputError(f"{where}: the checkpoint is of another problem: {what} differs{shown}")


def _close(x, y, scale: float = 0.0) -> bool:
    """x == y to :data:`IDENTITY_RTOL` of max(|x|, |y|, scale)."""
    if isinstance(x, str) or isinstance(y, str):
        return x == y
    x, y = float(x), float(y)
    return abs(x - y) <= IDENTITY_RTOL * max(abs(x), abs(y), scale, 1e-300) or x == y


# ----------------------------------------------------------------------------- contents
def state_arrays(run, state: State) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The state's arrays (``state/...``) and flags, the scheme's extra data checked against
    its declaration; an InputError for data a scheme did not declare."""
    declared = {**COMMON_STATE_FIELDS, **getattr(run.scheme, "state_fields", {})}
    arrays = {"U": state.U, "V": state.V, "A": state.A, "lam": state.lam}
    if state.lam_t is not None:
        arrays["lam_t"] = state.lam_t
    flags = {}
    for key, value in state.extra.items():
        kind = declared.get(key)
        if kind is None:
            raise InputError(
                f"scheme {run.scheme.name} keeps {key!r} in State.extra without declaring it in its state_fields "
                f"(kinds: {', '.join(STATE_FIELD_KINDS)}): a checkpoint cannot save it"
            )
        if value is None:
            continue
        if kind == "flag":
            flags[key] = bool(value)
        else:
            arrays[f"extra/{key}"] = np.asarray(value)
    return arrays, flags


def _expected_shape(kind: str, run) -> tuple[int, ...]:
    n, nc = run.ctx.disc.space.n_dofs, run.ctx.disc.contact.size
    return {
        "dofs": (n,),
        "contact": (nc,),
        "contact_t": (nc, run.ctx.rows.components - 1),
        "fixed": (run.ctx.fixed.size,),
    }[kind]


def restore_state(run, arrays: dict[str, np.ndarray], flags: dict[str, Any], t: float) -> State:
    """The :class:`State` of a checkpoint, every array's shape and finiteness checked."""
    n, nc = run.ctx.disc.space.n_dofs, run.ctx.disc.contact.size
    expect = {"U": (n,), "V": (n,), "A": (n,), "lam": (nc,)}
    if run.ctx.rows.components > 1 and "lam_t" in arrays:
        expect["lam_t"] = (nc, run.ctx.rows.components - 1)
    declared = {**COMMON_STATE_FIELDS, **getattr(run.scheme, "state_fields", {})}
    extra: dict[str, Any] = {}
    for key, a in arrays.items():
        if key.startswith("extra/"):
            name = key[6:]
            if name not in declared or declared[name] == "flag":
                raise InputError(f"checkpoint: state field {name!r} is not data of scheme {run.scheme.name}")
            expect[key] = _expected_shape(declared[name], run)
            extra[name] = a
    for key, shape in expect.items():
        a = arrays.get(key)
        if a is None:
            raise InputError(f"checkpoint: the state has no {key!r}")
        if a.shape != shape:
            raise InputError(f"checkpoint: state field {key!r} has shape {a.shape}, expected {shape}")
        if a.dtype != np.float64:
            raise InputError(f"checkpoint: state field {key!r} is {a.dtype}, expected float64")
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            raise InputError(f"checkpoint: state field {key!r} holds non-finite values")
    for key, v in flags.items():
        if declared.get(key) != "flag":
            raise InputError(f"checkpoint: flag {key!r} is not data of scheme {run.scheme.name}")
        extra[key] = bool(v)
    lam_t = arrays.get("lam_t") if run.ctx.rows.components > 1 else None
    return State(
        float(t),
        arrays["U"].copy(),
        arrays["V"].copy(),
        arrays["A"].copy(),
        arrays["lam"].copy(),
        extra={k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in extra.items()},
        lam_t=None if lam_t is None else lam_t.copy(),
    )


# ----------------------------------------------------------------------------- file
def flatten(prefix: str, data: dict[str, Any], arrays: dict, attrs: dict) -> None:
    """Arrays of ``data`` under ``prefix/key``; everything else as JSON in ``attrs``."""
    for k, v in data.items():
        if isinstance(v, np.ndarray) and v.dtype.kind in "biuf":
            arrays[f"{prefix}/{k}"] = v
        else:
            attrs[f"{prefix}/{k}"] = v


def _digest(arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> str:
    h = hashlib.blake2b(digest_size=16)
    for k in sorted(arrays):
        a = np.ascontiguousarray(arrays[k])
        h.update(f"{k}|{a.dtype.str}|{a.shape}".encode())
        h.update(a.data)
    h.update(json.dumps(attrs, sort_keys=True, default=str).encode())
    return h.hexdigest()


def write(path: Path, contents: dict[str, Any]) -> int:
    """Write ``contents`` (``arrays``: name -> array, ``attrs``: name -> JSON-able value) to
    ``path`` atomically: a temporary file beside it, fsync, rename.  Returns its size [B]."""
    import h5py

    path = Path(path)
    arrays, attrs = contents["arrays"], dict(contents["attrs"])
    attrs["format"], attrs["version"] = FORMAT, VERSION
    attrs["checksum"] = _digest(arrays, {k: v for k, v in attrs.items() if k != "checksum"})
    # the HDF5 image is made in memory and written by Python: a full disk or a file-size
    # limit is an OSError here, never a failure inside the HDF5 library (which then crashes
    # the process when the file is closed; the field writer runs in a child for that reason)
    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        for k, a in arrays.items():
            f.create_dataset(k, data=a)
        for k, v in attrs.items():
            f.attrs[k] = json.dumps(v)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(buf.getbuffer())
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_directory(path.parent)
    return len(buf.getbuffer())


def _fsync_directory(directory: Path) -> None:
    try:
        dfd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


# ----------------------------------------------------------------------------- per-level series
def series_path(path: Path) -> Path:
    """The file of a checkpoint's per-level series: ``checkpoint.h5`` -> ``checkpoint.series``."""
    path = Path(path)
    return path.with_name(path.stem + ".series")


class SeriesLog:
    """The per-level series of a run (history, energies, untagged watch) appended to a raw
    file of fixed-size records, one per level, beside the checkpoint, so that a checkpoint
    costs the levels since the previous one, not the whole history (the checkpoint h5 holds
    the layout, the number of valid records and a running digest of them).

    A kill during an append leaves the previous checkpoint valid: it counts only its records.
    """

    def __init__(self) -> None:
        self.layout: list[tuple[str, str, tuple[int, ...]]] | None = None
        self.written = 0  # records in the file (levels 0 .. written - 1)
        self.digests: list[Any] = []  # the running digest after each checkpoint's records
        self.path: Path | None = None
        self._hash = hashlib.blake2b(digest_size=16)

    def record_bytes(self) -> int:
        return sum(int(np.dtype(t).itemsize * np.prod(s, dtype=np.int64)) for _, t, s in self.layout)

    def append(self, path: Path, series: dict[str, np.ndarray], n: int) -> tuple[list, int, str]:
        """Write the records of the levels not yet written up to n; returns (layout, records,
        digest of records 0..n)."""
        path = Path(path)
        layout = [(k, np.asarray(v).dtype.str, tuple(np.shape(v)[1:])) for k, v in sorted(series.items())]
        if self.layout != layout or self.path != path or self.written > n + 1:  # a new file
            self.layout, self.path, self.written = layout, path, 0
            self._hash = hashlib.blake2b(digest_size=16)
        if self.written < n + 1:
            rows = slice(self.written, n + 1)
            block = np.concatenate(
                [
                    np.ascontiguousarray(np.asarray(series[k])[rows]).view(np.uint8).reshape(rows.stop - rows.start, -1)
                    for k, _, _ in layout
                ],
                axis=1,
            )
            with open(path, "r+b" if self.written and path.exists() else "wb") as fh:
                fh.seek(self.written * self.record_bytes())
                fh.write(block.tobytes())
                fh.truncate()
                fh.flush()
                os.fsync(fh.fileno())
            self._hash.update(block.tobytes())
            self.written = n + 1
        return [list(x[:2]) + [list(x[2])] for x in layout], n + 1, self._hash.hexdigest()


def read_series(path: Path, layout: list, records: int, digest: str, where: str) -> dict[str, np.ndarray]:
    """The series of the first ``records`` records of a checkpoint's series file, checked
    against its layout and digest (an InputError for a short, edited or missing file)."""
    try:
        lay = [(str(k), np.dtype(t), tuple(int(x) for x in s)) for k, t, s in layout]
        if any(x < 0 for _, _, s in lay for x in s):
            raise ValueError("a negative dimension")
        size = sum(t.itemsize * math.prod(s) for _, t, s in lay)  # Python integers: no overflow
        records = int(records)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{where}: its series layout is malformed ({exc})") from None
    p = series_path(path)
    if not p.is_file():
        raise InputError(f"{where}: its series file {p.name} is missing (it holds the levels before the checkpoint)")
    need = size * records
    if records < 0 or size <= 0 or need > p.stat().st_size:  # checked before anything is read or allocated
        raise InputError(
            f"{where}: its series file {p.name} is shorter than the checkpoint says ({records} records of "
            f"{size} bytes; a truncated or forged file)"
        )
    with open(p, "rb") as fh:
        raw = fh.read(need)
    if len(raw) != need:
        raise InputError(f"{where}: its series file {p.name} is truncated ({len(raw)} of {need} bytes)")
    if hashlib.blake2b(raw, digest_size=16).hexdigest() != digest:
        raise InputError(f"{where}: its series file {p.name} does not match the checkpoint (edited or of another run)")
    table = np.frombuffer(raw, dtype=np.uint8).reshape(records, size) if records else np.zeros((0, size), np.uint8)
    out, col = {}, 0
    for k, t, s in lay:
        width = t.itemsize * math.prod(s)
        out[k] = np.ascontiguousarray(table[:, col : col + width]).view(t).reshape((records,) + s)
        col += width
    return out


def _open(path: Path, arrays: bool) -> dict[str, Any]:
    """The attributes (and, with ``arrays``, the datasets) of a checkpoint file, its format
    and version checked: an InputError (one line) for anything else."""
    path = Path(path)
    where = f"checkpoint {str(path)!r}"
    if path.is_dir():
        raise InputError(f"{where} is a directory, not a checkpoint file (give the checkpoint.h5 inside a result)")
    if not path.is_file():
        raise InputError(f"{where}: no such file (every run of `signorini run` writes it at its end)")
    data: dict[str, np.ndarray] = {}
    try:
        import h5py

        with h5py.File(path, "r") as f:
            attrs = {k: json.loads(f.attrs[k]) for k in f.attrs}
            if attrs.get("format") == FORMAT and isinstance(attrs.get("version"), int) and arrays:
                f.visititems(lambda name, obj: data.__setitem__(name, obj[()]) if hasattr(obj, "shape") else None)
    except Exception as exc:  # truncated, corrupt: h5py raises OSError, KeyError, ValueError, ...
        first = str(exc).splitlines()[0] if str(exc) else ""
        raise InputError(f"{where}: unreadable ({type(exc).__name__}: {first}); a truncated or corrupt file") from None
    if attrs.get("format") != FORMAT:
        raise InputError(f"{where}: not a signorini checkpoint (format {attrs.get('format')!r})")
    if not isinstance(attrs.get("version"), int) or attrs["version"] > VERSION:
        raise InputError(
            f"{where}: format version {attrs.get('version')!r} is newer than this signorini reads "
            f"({VERSION}); resume it with the signorini that wrote it"
        )
    return {"arrays": data, "attrs": attrs}


def check_attrs(attrs: dict[str, Any], where: str) -> None:
    """The types and ranges of a checkpoint's attributes (a file whose checksum was forged
    gets a one-line refusal, not a failure further on)."""

    def bad(what: str) -> InputError:
        return InputError(f"{where}: malformed checkpoint: {what}")

    level, t, dt = attrs.get("level"), attrs.get("t"), attrs.get("dt")
    if not isinstance(level, int) or isinstance(level, bool) or level < 0:
        raise bad(f"level {level!r} is not a non-negative integer")
    for name, v in (("t", t), ("dt", dt)):
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v):
            raise bad(f"{name} {v!r} is not a finite number")
    if not dt > 0 or t < 0:
        raise bad(f"dt = {dt!r} or t = {t!r} out of range")
    for name, kind in (("identity", dict), ("counters", dict), ("series", dict)):
        if not isinstance(attrs.get(name), kind):
            raise bad(f"{name} is missing or not a {kind.__name__}")
    for name, kind in (("state/flags", dict), ("solvers/count", int)):  # (or their former names: :func:`upgrade`)
        value = attrs.get(name, attrs.get(LAYOUT_NAMES[name], kind()))
        if not isinstance(value, kind) or isinstance(value, bool):
            raise bad(f"{name} is not a {kind.__name__}")
    if any(not isinstance(v, int) or isinstance(v, bool) or v < 0 for v in attrs["counters"].values()):
        raise bad("a counter is not a non-negative integer")
    seg = attrs.get("segment")

    def finite(x) -> bool:
        try:
            return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(float(x))
        except OverflowError:
            return False

    if seg is not None and (
        not isinstance(seg, list)
        or len(seg) != 3
        or not all(finite(x) for x in seg)
        or not seg[1] > 0
        or not isinstance(seg[2], int)
        or not 0 <= seg[2] <= level
    ):
        raise bad(f"segment {seg!r} is not [start, dt > 0, first level <= level]")


def read_meta(path: Path) -> dict[str, Any]:
    """The attributes of a checkpoint (level, t, identity, meta), format and version checked
    (the arrays and the checksum are checked when the run resumes: :func:`read`)."""
    attrs = _open(path, arrays=False)["attrs"]
    check_attrs(attrs, f"checkpoint {str(path)!r}")
    return attrs


def read(path: Path) -> dict[str, Any]:
    """The ``arrays`` and ``attrs`` of a checkpoint file, its format, version and checksum
    checked: an InputError (one line) for anything else than a complete checkpoint."""
    contents = _open(path, arrays=True)
    arrays, attrs = contents["arrays"], contents["attrs"]
    where = f"checkpoint {str(path)!r}"
    checksum = attrs.pop("checksum", None)
    if checksum != _digest(arrays, attrs):
        raise InputError(f"{where}: its checksum does not match its contents (a corrupt or edited file)")
    check_attrs(attrs, where)
    return {"arrays": arrays, "attrs": attrs}


#: attributes a checkpoint of before the parts' walk named otherwise (new name: former name); still read
LAYOUT_NAMES = {"state/flags": "state_flags", "solvers/count": "n_solvers"}


def upgrade(contents: dict[str, Any]) -> dict[str, Any]:
    """A checkpoint's contents with the attributes of before the parts' walk under their names now
    (:data:`LAYOUT_NAMES`): a checkpoint written by an earlier version of the same format resumes."""
    attrs = dict(contents["attrs"])
    for new, old in LAYOUT_NAMES.items():
        if old in attrs:
            attrs.setdefault(new, attrs.pop(old))
    return {**contents, "attrs": attrs}


def unflatten(prefix: str, contents: dict[str, Any]) -> dict[str, Any]:
    """The entries under ``prefix/`` (arrays and JSON values), keyed by the rest of the name."""
    out: dict[str, Any] = {}
    p = prefix + "/"
    for k, v in contents["arrays"].items():
        if k.startswith(p):
            out[k[len(p) :]] = v
    for k, v in contents["attrs"].items():
        if k.startswith(p):
            out[k[len(p) :]] = v
    return out


class CheckpointLog:
    """What the run's checkpoints cost: count, seconds, bytes of the last, its level
    (``summary.json`` ``checkpoints``)."""

    def __init__(self, every: int, path) -> None:
        self.every, self.path = int(every), path
        self.written, self.seconds, self.bytes, self.level = 0, 0.0, 0, -1
        self.error, self.failed = "", 0

    def timed(self, write_fn) -> None:
        t0 = time.perf_counter()
        self.bytes = write_fn()
        self.seconds += time.perf_counter() - t0
        self.written += 1

    def summary(self) -> dict[str, Any]:
        out = {
            "every": self.every,
            "written": self.written,
            "seconds": self.seconds,
            "bytes": self.bytes,
            "level": self.level,
        }
        if self.error:
            out["error"], out["failed"] = self.error, self.failed
        return out
