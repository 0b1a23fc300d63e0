"""Run files that survive a kill: JSON written atomically, JSON lines appended and flushed as they come,
NumPy archives renamed into place."""

from __future__ import annotations

import json
import math
import os
import tempfile
from typing import Any, Iterable

import numpy as np


def write_json_atomic(path: str, obj: Any) -> None:
    """Writes JSON to a temporary file in the same folder, then renames it over ``path``."""
    write_text_atomic(path, json.dumps(obj, indent=2, default=_jsonable))


def write_text_atomic(path: str, data: str | bytes) -> None:
    """Writes text (or bytes) to a temporary file in the same folder, then renames it over ``path``: a reader
    sees the old file or the new one, never half of one."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=os.path.splitext(path)[1])
    mask = os.umask(0)
    os.umask(mask)
    try:
        os.chmod(tmp, 0o666 & ~mask)  # the mode open() gives a new file (mkstemp's is 0600)
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode() if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _jsonable(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x)}")


def json_number(x: float) -> float | None:
    """A number for JSON: None for NaN and infinities."""
    x = float(x)
    return None if math.isnan(x) or math.isinf(x) else x


def json_numbers(x: Any) -> Any:
    """``x`` (dicts and lists of them, numbers, strings) with every float through ``json_number``."""
    if isinstance(x, dict):
        return {k: json_numbers(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_numbers(v) for v in x]
    return json_number(x) if isinstance(x, float) else x


class JsonlWriter:
    """Appends JSON lines and flushes after every batch, so a killed run keeps what it wrote."""

    def __init__(self, path: str):
        self.path = path
        self._f = open(path, "a")

    def write(self, rows: Iterable[dict]) -> None:
        for row in rows:
            self._f.write(json.dumps(row, default=_jsonable) + "\n")
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self) -> None:
        self._f.close()


def truncate_jsonl(path: str, keep) -> None:
    """Keeps the rows for which ``keep(row)`` holds (drops rows written after a checkpoint), atomically."""
    if not os.path.exists(path):
        return
    kept = [row for row in read_jsonl(path) if keep(row)]
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.writelines(json.dumps(row) + "\n" for row in kept)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def read_jsonl(path: str) -> list[dict]:
    """The rows of a JSONL file; a last line cut by a kill is skipped."""
    rows = []
    with open(path) as f:
        for line in f:
            if not line.strip():
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return rows


def savez_atomic(path: str, arrays: dict) -> None:
    """``np.savez_compressed`` to a temporary name in the same folder, then renamed over ``path``."""
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, path)
