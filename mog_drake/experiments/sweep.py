"""Resumable, parallel sweeps: one JSON line per finished task, appended as it completes.

An interrupted sweep (Ctrl-C, a killed machine) resumes where it stopped: finished tasks are
read back from ``results.jsonl`` and skipped; a torn last line is dropped. ``jobs`` runs tasks
in parallel processes on this machine; ``ray_address`` sends them to an existing Ray cluster.

A task that raises does not stop the others: its error and traceback are appended to
``failures.jsonl``, the remaining tasks run, and the sweep then raises one ``MogError`` naming
the failed tasks. They have no result, so the next run of the same command retries them.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import traceback
from collections.abc import Callable, Iterable
from pathlib import Path

from mog_drake.errors import MogError
from mog_drake.progress import Progress


def load_results(path: Path, repair: bool = True) -> dict[str, dict]:
    """Finished results by key. A torn (unterminated) last line is left out; with ``repair``
    it is also cut from the file, which only the sweep about to append to it may do: read
    while another process is writing, that line is still being written."""
    path = Path(path)
    if not path.exists():
        return {}
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        data = data[: data.rfind(b"\n") + 1]
        if repair:
            path.write_bytes(data)
    out = {}
    for line in data.decode().splitlines():
        if line.strip():
            rec = json.loads(line)
            out[rec["key"]] = rec
    return out


def check_params(out_dir: Path, params: dict, growable: Iterable[str] = ("scenes_per_class",)) -> None:
    """Records the sweep's parameters; refuses to resume a folder made with different ones
    (except the ``growable`` ones, which may change: a larger sweep extends a smaller one)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "sweep.json"
    if path.exists():
        old = json.loads(path.read_text())
        diff = [k for k in set(old) | set(params) if k not in growable and old.get(k) != params.get(k)]
        if diff:
            k = sorted(diff)[0]
            raise MogError(
                f"{out_dir} holds a sweep with {k}={_short(old.get(k))}, not {_short(params.get(k))}: "
                "use another --out folder"
            )
    path.write_text(json.dumps(params, indent=2))


def _short(value, n: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= n else text[: n - 3] + "..."


_SUMMARY_ONLY = False


@contextlib.contextmanager
def summary_only():
    """Inside this block sweeps run nothing: they return the results already written, so a
    summary of a sweep still under way (or interrupted) can be printed."""
    global _SUMMARY_ONLY
    before, _SUMMARY_ONLY = _SUMMARY_ONLY, True
    try:
        yield
    finally:
        _SUMMARY_ONLY = before


def run_sweep(
    tasks: list[dict],
    worker: Callable[[dict], dict],
    out_dir: str | Path,
    jobs: int = 1,
    ray_address: str | None = None,
    label: str = "sweep",
    progress: bool = True,
) -> list[dict]:
    """Runs ``worker(task)`` for every task whose ``key`` has no result yet; returns all
    results in task order. ``worker`` must be a module-level function (it is pickled).
    Raises ``MogError`` after the last task if any task raised (see the module's docstring)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "results.jsonl"
    # A summary of a sweep still under way only reads: it must not touch the file.
    done = load_results(path, repair=not _SUMMARY_ONLY)
    if _SUMMARY_ONLY:
        return [done[t["key"]] for t in tasks if t["key"] in done]
    todo = [t for t in tasks if t["key"] not in done]
    bar = Progress(len(tasks), label, enabled=progress, start=len(tasks) - len(todo))
    bar.update(len(tasks) - len(todo))
    failed: list[dict] = []
    try:
        with open(path, "a") as f:
            for rec in _execute(todo, worker, jobs, ray_address):
                if _FAILED in rec:
                    failed.append(rec)
                    _append_line(out_dir / "failures.jsonl", rec)
                else:
                    _write_line(f, rec)
                    done[rec["key"]] = rec
                bar.step()
    finally:
        bar.close()
    if failed:
        first = failed[0]
        raise MogError(
            f"{len(failed)} of {len(todo)} {label} tasks failed (first: {first['key']}: "
            f"{first[_FAILED]}); tracebacks in {out_dir / 'failures.jsonl'}; the other results "
            "are kept and running the same command again retries the failed tasks"
        )
    return [done[t["key"]] for t in tasks if t["key"] in done]


_FAILED = "sweep_error"


def _guarded(worker: Callable[[dict], dict], task: dict) -> dict:
    """``worker(task)``, or a failure record if it raised (in the worker's own process, so the
    traceback survives pickling)."""
    try:
        return worker(task)
    except Exception as e:
        return {
            "key": task["key"],
            _FAILED: f"{type(e).__name__}: {e}".splitlines()[0],
            "traceback": traceback.format_exc(),
        }


def _write_line(f, rec: dict) -> None:
    f.write(json.dumps(rec) + "\n")
    f.flush()
    os.fsync(f.fileno())


def _append_line(path: Path, rec: dict) -> None:
    with open(path, "a") as f:
        _write_line(f, rec)


def _execute(tasks: list[dict], worker, jobs: int, ray_address: str | None):
    if not tasks:
        return
    if ray_address:
        yield from _execute_ray(tasks, worker, ray_address)
    elif jobs <= 1:
        for t in tasks:
            yield _guarded(worker, t)
    else:
        import multiprocessing as mp

        # spawn: fresh interpreters, nothing of the parent's Drake state is shared.
        with mp.get_context("spawn").Pool(jobs) as pool:
            yield from pool.imap_unordered(functools.partial(_guarded, worker), tasks, chunksize=1)


def _execute_ray(tasks: list[dict], worker, address: str):
    try:
        import ray
    except ImportError:
        raise MogError("--ray needs Ray: pip install 'mog_drake[ray]'") from None
    ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(_guarded)
    pending = [remote.remote(worker, t) for t in tasks]
    while pending:
        ready, pending = ray.wait(pending, num_returns=1)
        yield ray.get(ready[0])
