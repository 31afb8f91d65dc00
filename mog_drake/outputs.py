"""Output files that cannot lose work: checked before a run, written whole or not at all."""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path

from mog_drake.errors import MogError


def check_writable(path: str | Path, what: str) -> None:
    """Refuses, before anything runs, a file that could not be written at the end: its folder
    is made if missing and a probe file is created in it and removed."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with _temporary(path) as probe:
            probe.write_bytes(b"")
    except OSError as e:
        raise MogError(f"{what} {path}: cannot be written ({e.strerror or e})") from None


@contextlib.contextmanager
def _temporary(path: Path):
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        yield tmp
    finally:
        tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_path(path: str | Path):
    """A temporary path beside ``path`` (same suffix, so writers that go by it still do) that
    replaces ``path`` only once the block ends without error: a write cut short by a signal or
    a full disk leaves the earlier file whole."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _temporary(path) as tmp:
        yield tmp
        os.replace(tmp, path)


def write_atomic(path: str | Path, text: str) -> Path:
    """Writes ``text`` to ``path`` whole or not at all (`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def plain(obj):
    """``obj`` as strict JSON values: NaN and infinities become null (JSON has no NaN),
    numpy scalars and arrays Python numbers and lists."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return plain(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
