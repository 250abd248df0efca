"""A recording's table as Apache Parquet (pyarrow): the same columns as the CSV format.

One float64 column per channel, ``time`` [s] first; the sidecar metadata that a CSV keeps in
``<name>.json`` is stored as JSON in the Parquet schema metadata under :data:`META_KEY`, so
one file carries both.  Reading applies the CSV reader's checks (``time`` present, no
repeated column, numbers only, no NaN/inf/null, at least 2 rows, strictly increasing time)
with the same messages; rows are counted from 1 (a CSV's line number is the row + 1).
Column names lose surrounding spaces and a leading byte-order mark, as a CSV header does.

This module works on plain arrays (``time``, ``columns``, ``meta``) so that
:mod:`pneumatics.recording` can build on it without an import cycle.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..io import atomic_save
from .rows import check_rows

META_KEY = b"pneumasim.meta"
"""Parquet schema-metadata key of the recording's metadata (JSON)."""


def write_table(path: str | Path, time: np.ndarray, columns: dict, meta: dict):
    """Write ``time`` and ``columns`` (name -> (N,) array) to ``path`` atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    names = ["time", *columns]
    arrays = [pa.array(np.asarray(v, dtype=float)) for v in (time, *columns.values())]
    schema_meta = {META_KEY: json.dumps(meta).encode()} if meta else None
    table = pa.Table.from_arrays(arrays, names=names, metadata=schema_meta)
    atomic_save(path, lambda tmp: pq.write_table(table, tmp))


def read_table(path: str | Path) -> tuple[np.ndarray, dict[str, np.ndarray], dict]:
    """``(time, columns, meta)`` of a Parquet recording; RecordingError naming file, row, column."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"{path}: recording not found")
    try:
        table = pq.ParquetFile(path).read()
    except (pa.ArrowException, OSError) as e:
        raise RecordingError(f"{path}: not a readable Parquet file ({e})") from None
    # as a CSV header is read: spaces around a name and a byte-order mark (a table converted
    # from Excel's "CSV UTF-8") are not part of it
    header = [name.lstrip("\ufeff").strip() for name in table.column_names]
    if "time" not in header:
        raise RecordingError(f"{path}: no 'time' column in the header (got {', '.join(header[:8])}...)")
    dup = {h for h in header if header.count(h) > 1}
    if dup:
        raise RecordingError(f"{path}: repeated column(s) {sorted(dup)}")
    data = np.empty((table.num_rows, len(header)))
    for j, name in enumerate(header):
        data[:, j] = _numbers(path, name, table.column(j))
    check_rows(path, header, data, first=1, word="row")
    t = data[:, header.index("time")]
    columns = {h: data[:, j].copy() for j, h in enumerate(header) if h != "time"}
    return t.copy(), columns, _meta(path, table.schema.metadata)


def _numbers(path: Path, name: str, column) -> np.ndarray:
    """A column as float64: integer and floating types only, no nulls."""
    import pyarrow.types as pat

    kind = column.type
    if not (pat.is_floating(kind) or pat.is_integer(kind)):
        raise RecordingError(f"{path}: column {name!r} holds {kind} values, expected numbers "
                             "(float or integer)")
    if column.null_count:
        row = int(np.flatnonzero(column.is_null().to_numpy(zero_copy_only=False))[0])
        raise RecordingError(f"{path}: row {row + 1}, column {name!r} is null "
                             f"({column.null_count} null value(s) in all); clean or cut the recording")
    return column.to_numpy().astype(float)


def _meta(path: Path, schema_meta: dict | None) -> dict:
    """The recording's metadata: the schema's :data:`META_KEY`, else a sidecar ``<name>.json``."""
    if schema_meta and META_KEY in schema_meta:
        try:
            meta = json.loads(schema_meta[META_KEY])
        except json.JSONDecodeError as e:
            raise RecordingError(f"{path}: schema metadata {META_KEY.decode()!r} is not valid JSON: {e}") from None
        if not isinstance(meta, dict):
            raise RecordingError(f"{path}: schema metadata {META_KEY.decode()!r} is not a JSON object")
        return meta
    side = path.with_suffix(".json")
    if side.is_file():
        try:
            return json.loads(side.read_text())
        except json.JSONDecodeError as e:
            raise RecordingError(f"{side}: sidecar is not valid JSON: {e}") from None
    return {}
