"""Atomic file writes for every package: a temporary file in the target's folder, then ``os.replace``.

A reader never sees a half-written file, and a write that fails (or is killed) leaves the previous file
intact and no temporary file behind (except after a hard kill, as a hidden ``.<name>.<pid>.<random>.tmp``).
The new file gets the permissions of any other new file (``0o666`` less the umask); bytes written here
are flushed to the disk before the rename.

Examples:
    >>> import json, tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> write_json_atomic(folder / "a.json", {"b": 1})
    >>> json.loads((folder / "a.json").read_text())
    {'b': 1}
    >>> with atomic_path(folder / "lines.txt") as tmp:  # any writer: here, a stream of lines
    ...     with tmp.open("w") as stream:
    ...         print("one", file=stream)
    >>> (folder / "lines.txt").read_text().split(), sorted(p.name for p in folder.iterdir())
    (['one'], ['a.json', 'lines.txt'])
"""

from __future__ import annotations

import json
import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = ["atomic_path", "write_bytes_atomic", "write_text_atomic", "write_json_atomic"]


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path``, on error it is removed.

    The temporary path is unique (process id and a random token) and does not exist yet; the caller
    creates it by any means (its name ends in ``.tmp``, so writers that infer a format from the suffix
    must be told the format).
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically, flushed to the disk before it replaces the old file."""
    with atomic_path(path) as tmp, tmp.open("wb") as handle:
        handle.write(data)
        handle.flush()
        os.fsync(handle.fileno())


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write a UTF-8 text file atomically (newlines as given, never translated)."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | Path, data: Any) -> None:
    """Write JSON (sorted keys, indented) atomically."""
    write_text_atomic(path, json.dumps(data, indent=1, sort_keys=True) + "\n")
