"""The files the project reads and writes. Reads: regular files only, bounded in size (a FIFO
would block, /dev/zero never end), each refusal one line naming the file. Writes: checked
before a run, written whole or not at all, so no work is lost."""

from __future__ import annotations

import contextlib
import math
import os
import stat
from pathlib import Path

from mog_drake.errors import MogError

# A scene, shapes or scenario file is a few kB (a 300-object scene about 20 kB): a larger one
# is not one, and YAML takes seconds per MB to refuse.
MAX_TEXT_BYTES = 2**20
# A sweep's results (JSON lines, a few kB per run) or a recorded camera frame (about 2 MB).
MAX_DATA_BYTES = 2**30


def model_path(name: str) -> Path:
    """A file shipped with the package in ``models/``: the resource package
    ``mog_drake.models`` of an installed package (a wheel, or an editable install that maps it
    onto the checkout's top-level ``models/``), or that folder itself when ``mog_drake`` is
    imported straight from a source tree (``python -m mog_drake.cli`` in a checkout or a
    worktree). Its path on disk."""
    from importlib.resources import files

    try:
        return Path(str(files("mog_drake.models") / name))
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[1] / "models" / name


def read_bytes(path: str | Path, what: str = "file", limit: int = MAX_DATA_BYTES) -> bytes:
    """A regular file's contents, or one `MogError` line saying why not: missing, a
    directory, not a regular file (a FIFO, a device), unreadable, or over ``limit`` bytes."""
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise MogError(f"{what} not found: {path}") from None
    except OSError as e:
        raise MogError(f"{path}: cannot be read ({e.strerror or e})") from None
    if stat.S_ISDIR(st.st_mode):
        raise MogError(f"{path}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise MogError(f"{path}: not a regular file, not a {what}")
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)  # bounded, whatever the file says its size is
    except PermissionError:
        raise MogError(f"{path}: permission denied") from None
    except OSError as e:
        raise MogError(f"{path}: cannot be read ({e.strerror or e})") from None
    if len(data) > limit:
        size = (
            f"{limit // 2**30} GiB"
            if limit >= 2**30
            else f"{limit // 2**20} MiB"
            if limit >= 2**20
            else f"{limit} bytes"
        )
        raise MogError(f"{path}: over {size}, not a {what}")
    return data


def read_text(path: str | Path, what: str = "file", limit: int = MAX_TEXT_BYTES) -> str:
    """A UTF-8 text file's contents (`read_bytes`), or one `MogError` line."""
    try:
        return read_bytes(path, what, limit).decode("utf-8")
    except UnicodeDecodeError:
        raise MogError(f"{path}: not a text file") from None


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
