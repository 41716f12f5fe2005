"""The sweep's Parquet dataset: one file per chunk, written atomically, and the manifest that ``--resume`` reads.

Layout of ``DIR``::

    DIR/_sweep.json            the manifest: scene, spec, seed, chunk size, gyrosim version (JSON)
    DIR/chunk-000000.parquet   samples [0, K)
    DIR/chunk-000001.parquet   samples [K, 2K) ...

A chunk file is written to a hidden temporary name (``.chunk-000001.parquet.<pid>.tmp``) and renamed (atomic on
POSIX), so a file that exists is complete: an interrupted or killed run leaves whole chunks only, and ``--resume``
computes the chunks whose file is missing. (No fsync: after a power loss a renamed file may lack its data;
``--resume`` reads each file's footer and row count and computes again a chunk whose file does not read.) Readers
(``pyarrow.parquet.read_table(DIR)``, ``pyarrow.dataset``, pandas, polars, DuckDB) skip names starting with ``_`` or
``.`` and see the chunks as one table.

Each file's schema metadata holds ``gyrosim.scene``, ``gyrosim.spec`` (JSON), ``gyrosim.seed`` and
``gyrosim.version``; nothing that depends on where or when it ran, so a local and a cluster run give byte-identical
files.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from .._atomic import atomic_open, atomic_path
from ..errors import ConfigError, GyrosimError

__all__ = ["MANIFEST", "chunk_path", "schema", "write_chunk", "present_chunks", "prepare_output", "read_sweep",
           "require_pyarrow"]

MANIFEST = "_sweep.json"
_CHUNK_RE = re.compile(r"^chunk-(\d{6,})\.parquet$")
FORMAT = 1


def require_pyarrow():
    """``pyarrow`` and ``pyarrow.parquet``, or a GyrosimError saying how to install them."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:  # pragma: no cover - pyarrow is in the sweep and test extras
        raise GyrosimError("the sweep writes Parquet with pyarrow, which is not installed: "
                           "pip install 'gyrosim[sweep]'") from None
    return pa, pq


def chunk_path(out: Path, k: int) -> Path:
    return Path(out) / f"chunk-{k:06d}.parquet"


def _metadata(spec) -> dict:
    return {b"gyrosim.scene": json.dumps(spec.scene_dict(), sort_keys=True).encode(),
            b"gyrosim.spec": json.dumps(spec.spec_dict(), sort_keys=True).encode(),
            b"gyrosim.seed": str(spec.seed).encode(),
            b"gyrosim.version": spec.version.encode()}


def schema(spec):
    """The Arrow schema of every chunk file (columns of :func:`gyrosim.sweep.runner.result_columns`)."""
    pa, _ = require_pyarrow()
    from .runner import result_columns

    types = {"int": pa.int64(), "float": pa.float64(), "str": pa.string(), "bool": pa.bool_()}
    return pa.schema([pa.field(c, types[kind], nullable=kind == "str") for c, kind in result_columns(spec)],
                     metadata=_metadata(spec))


def write_chunk(out: Path, k: int, columns: dict, sch) -> Path:
    """Write chunk ``k`` (columns as numpy arrays) atomically; return its path."""
    pa, pq = require_pyarrow()
    table = pa.Table.from_arrays([pa.array(columns[f.name], type=f.type) for f in sch], schema=sch)
    final = chunk_path(out, k)
    with atomic_path(final) as tmp:
        pq.write_table(table, tmp, compression="zstd")
    return final


def present_chunks(out: Path, spec) -> set[int]:
    """The chunks of ``spec`` whose file in ``out`` is complete (its footer reads and has the chunk's rows)."""
    _, pq = require_pyarrow()
    have = set()
    for f in Path(out).iterdir():
        m = _CHUNK_RE.match(f.name)
        if not m:
            continue
        k = int(m.group(1))
        if k >= spec.n_chunks:
            continue
        a, b = spec.chunk_bounds(k)
        try:
            ok = pq.read_metadata(f).num_rows == b - a
        except (OSError, ValueError, Exception):  # noqa: BLE001 - any unreadable file is recomputed
            ok = False
        if ok:
            have.add(k)
    return have


def _manifest(spec) -> dict:
    return {"format": FORMAT, "gyrosim": spec.version, "scene": spec.scene_dict(), "spec": spec.spec_dict(),
            "chunk_size": spec.chunk_size, "n_chunks": spec.n_chunks}


def _differences(old: dict, new: dict, prefix: str = "") -> list[str]:
    diffs = []
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key), new.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            diffs += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            diffs.append(f"{prefix}{key}: {a!r} there, {b!r} now")
    return diffs


def read_manifest(out: Path) -> dict | None:
    f = Path(out) / MANIFEST
    if not f.is_file():
        return None
    try:
        return json.loads(f.read_text())
    except (OSError, ValueError) as e:
        raise ConfigError("--output", str(out), f"a sweep folder with a readable {MANIFEST} ({e})") from None


def prepare_output(out: Path, spec, resume: bool) -> set[int]:
    """Make ``out`` ready for ``spec``: a new folder with its manifest, or (``resume``) the folder of the same sweep;
    return the chunks already complete there. Leftover temporary files of an interrupted run are removed."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("--output", str(out), "a folder (this is a file)")
    old = read_manifest(out) if out.is_dir() else None
    if old is None:
        if out.is_dir() and any(out.iterdir()):
            if any(_CHUNK_RE.match(f.name) for f in out.iterdir()):
                raise ConfigError("--output", str(out), f"a folder with its {MANIFEST} (it has chunk files but no "
                                  "manifest): remove it or choose another folder")
            raise ConfigError("--output", str(out), "a new or empty folder (this one holds other files)")
        out.mkdir(parents=True, exist_ok=True)
        with atomic_open(out / MANIFEST, "w") as fh:
            fh.write(json.dumps(_manifest(spec), indent=1, sort_keys=True))
        return set()
    if not resume:
        raise ConfigError("--output", str(out), "a new or empty folder: this one holds a sweep already; pass "
                          "--resume to complete it, or choose another folder")
    new = _manifest(spec)
    diffs = _differences({k: old.get(k) for k in ("scene", "spec", "chunk_size", "gyrosim")},
                         {k: new[k] for k in ("scene", "spec", "chunk_size", "gyrosim")})
    if diffs:
        raise ConfigError("--resume", str(out), "the same sweep as the one there (same scene, spec, chunk size and "
                          "gyrosim version); it differs in " + "; ".join(diffs[:5]))
    for f in out.iterdir():
        if f.name.startswith(".") and f.name.endswith(".tmp"):
            f.unlink()
    return present_chunks(out, spec)


def read_sweep(out, columns=None):
    """The sweep at ``out`` as one ``pyarrow.Table``, sorted by ``sample``."""
    _, pq = require_pyarrow()
    out = Path(out)
    if not out.is_dir() or not any(_CHUNK_RE.match(f.name) for f in out.iterdir()):
        raise ConfigError("DIR", str(out), "a sweep folder with chunk-*.parquet files (gyrosim sweep --output DIR)")
    table = pq.read_table(out, columns=columns)
    if "sample" in table.column_names:
        table = table.sort_by("sample")
    return table
