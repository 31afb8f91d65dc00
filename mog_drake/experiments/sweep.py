"""Resumable, parallel sweeps: one JSON line per finished task, appended as it completes.

An interrupted sweep (Ctrl-C, a killed machine) resumes where it stopped: finished tasks are
read back from ``results.jsonl`` and skipped; a torn last line is dropped, and a corrupt line
anywhere is skipped with a one-line warning (its task runs again). One sweep at a time writes
to a folder: a lock on ``--out`` refuses a second one, naming the process that holds it.
Workers exit when their parent dies, however it dies. ``jobs`` runs tasks
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
import sys
import traceback
from collections.abc import Callable, Iterable
from pathlib import Path

from mog_drake.errors import MogError
from mog_drake.files import MAX_TEXT_BYTES, read_bytes
from mog_drake.progress import Progress


def load_results(
    path: Path, repair: bool = True, valid: Callable[[dict], bool] | None = None
) -> dict[str, dict]:
    """Finished results by key. A torn (unterminated) last line is left out, and so is any
    line that is not a JSON record with a "key", or that ``valid`` (the experiment's own
    test of a record's fields) refuses (each named in a one-line warning on stderr): its task
    has no result, so it runs again. With ``repair`` such lines are also cut from the
    file, which only the sweep about to append to it may do: read while another process is
    writing, the last line is still being written."""
    path = Path(path)
    if not path.exists():
        return {}
    data = read_bytes(path, "sweep's results (JSON lines)")
    torn = bool(data) and not data.endswith(b"\n")
    if torn:
        data = data[: data.rfind(b"\n") + 1]
    out, good, bad = {}, [], []
    for n, line in enumerate(data.split(b"\n")[:-1], start=1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            key = rec["key"]
            hash(key)
            if valid is not None and not valid(rec):
                raise ValueError("fields")
        except (ValueError, TypeError, KeyError, AttributeError):
            bad.append(n)
            continue
        out[key] = rec
        good.append(line)
    for n in bad:
        print(
            f"mog-drake: warning: {path} line {n} is not a result record; skipped (its task runs again)",
            file=sys.stderr,
        )
    if repair and (torn or bad):
        tmp = path.with_suffix(".jsonl.tmp")
        tmp.write_bytes(b"".join(line + b"\n" for line in good))
        os.replace(tmp, path)
    return out


def check_params(out_dir: Path, params: dict, growable: Iterable[str] = ("scenes_per_class",)) -> None:
    """Records the sweep's parameters; refuses to resume a folder made with different ones
    (except the ``growable`` ones, which may change: a larger sweep extends a smaller one).
    A summary only reads: it records nothing. Read, compared and written under the folder's
    lock, and written whole (renamed into place): two sweeps starting at once cannot both
    record theirs."""
    out_dir = Path(out_dir)
    if _SUMMARY_ONLY:
        _check_params(out_dir, params, growable)
        return
    with folder_lock(out_dir):
        _check_params(out_dir, params, growable)
        from mog_drake.files import write_atomic

        write_atomic(out_dir / "sweep.json", json.dumps(params, indent=2))


def read_params(out_dir: Path) -> dict | None:
    """A folder's sweep parameters (sweep.json), None if it has none; one line if it is not a
    JSON object."""
    path = Path(out_dir) / "sweep.json"
    if not path.exists():
        return None
    try:
        old = json.loads(read_bytes(path, "sweep's parameters (JSON)", MAX_TEXT_BYTES))
    except (ValueError, UnicodeDecodeError):
        old = None
    if not isinstance(old, dict):
        raise MogError(
            f"{path} is not a sweep's parameters (a JSON object): move it away or use another --out folder"
        )
    return old


def _check_params(out_dir: Path, params: dict, growable: Iterable[str]) -> None:
    old = read_params(out_dir)
    if old is None:
        return
    if old.get("experiment") != params.get("experiment"):
        raise MogError(
            f"{out_dir} holds a {old.get('experiment') or 'different'} sweep, not a "
            f"{params.get('experiment')} one: use another --out folder"
        )
    diff = [
        k
        for k in set(old) | set(params)
        if k not in growable and not same_param(k, old.get(k), params.get(k))
    ]
    if diff:
        k = sorted(diff)[0]
        raise MogError(
            f"{out_dir} holds a sweep with {k}={_short(old.get(k))}, not {_short(params.get(k))}: "
            "use another --out folder"
        )


def same_param(key: str, old, new) -> bool:
    """Whether a recorded parameter equals a new one. A scenario is YAML text: it is the same
    if it reads as the same document, so that a comment edited in the file after a sweep ran
    neither orphans the sweep's runs nor refuses its summary."""
    if old == new:
        return True
    if key != "scenario" or not (isinstance(old, str) and isinstance(new, str)):
        return False
    import yaml

    try:
        return yaml.safe_load(old) == yaml.safe_load(new)
    except yaml.YAMLError:
        return False


def _short(value, n: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= n else text[: n - 3] + "..."


_SUMMARY_ONLY = False


def reading_only() -> bool:
    """True inside `summary_only`: nothing may be written."""
    return _SUMMARY_ONLY


@contextlib.contextmanager
def folder_lock(out_dir: Path):
    """Holds an exclusive lock on ``out_dir`` (its ``.lock`` file, which names the holder's
    process id) for the block; a second sweep on the same folder is refused with one line."""
    import fcntl

    out_dir.mkdir(parents=True, exist_ok=True)
    for name in (".lock", "failures.jsonl"):  # appended to: a FIFO there would block the sweep
        p = out_dir / name
        if p.exists() and not p.is_file():
            raise MogError(f"{p}: not a regular file, not a sweep's {name}: move it away")
    f = open(out_dir / ".lock", "a+")  # noqa: SIM115
    try:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.seek(0)
            holder = f.read().strip() or "unknown"
            raise MogError(
                f"{out_dir} is in use by another sweep (process {holder}); wait for it to end or use another --out"
            ) from None
        f.seek(0)
        f.truncate()
        f.write(str(os.getpid()))
        f.flush()
        yield
    finally:
        f.close()  # releases the lock


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
    *,
    progress: bool = True,
    valid: Callable[[dict], bool] | None = None,
    note: str = "",
) -> list[dict]:
    """Runs ``worker(task)`` for every task whose ``key`` has no result yet; returns all
    results in task order. ``worker`` must be a module-level function (it is pickled).
    ``valid``: the experiment's test of a stored record (see `load_results`). ``note``: a
    line for stderr once the folder is read and tasks are left to run (with ``progress``).
    Raises ``MogError`` after the last task if any task raised (see the module's docstring)."""
    out_dir = Path(out_dir)
    path = out_dir / "results.jsonl"
    if _SUMMARY_ONLY:  # a summary of a sweep still under way only reads: it must not touch the file
        done = load_results(path, repair=False, valid=valid)
        return [done[t["key"]] for t in tasks if t["key"] in done]
    with folder_lock(out_dir):
        done = load_results(path, valid=valid)
        todo = [t for t in tasks if t["key"] not in done]
        if ray_address and todo:
            from mog_drake.experiments.cluster import connect

            connect(ray_address)  # refused in one line before anything runs
        if todo:
            _note_commit(out_dir)
            if note and progress:
                print(note, file=sys.stderr)
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
            if ray_address and todo:
                import ray

                # Let go of the cluster: a driver still connected when the cluster stops is
                # ended by Ray (exit 1), whatever this process is doing by then.
                ray.shutdown()
    if failed:
        first = failed[0]
        raise MogError(
            f"{len(failed)} of {len(todo)} {label} tasks failed (first: {first['key']}: "
            f"{first[_FAILED]}); tracebacks in {out_dir / 'failures.jsonl'}; the other results "
            "are kept and running the same command again retries the failed tasks"
        )
    return [done[t["key"]] for t in tasks if t["key"] in done]


def source_commit() -> str:
    """The git commit of the package's source (``+`` when its files differ from it), or "" when
    it is not a git checkout."""
    import subprocess

    here = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "--short=12", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        dirty = subprocess.run(
            [
                "git",
                "-C",
                str(here),
                "status",
                "--porcelain",
                "--untracked-files=no",
                "--",
                "mog_drake",
                "models",
            ],
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    if head.returncode != 0:
        return ""
    return head.stdout.strip() + ("+" if dirty.stdout.strip() else "")


def _note_commit(out_dir: Path) -> None:
    """Appends the source's commit to the folder's ``commits.txt`` (the commits its runs were
    made at), unless it is the last one there."""
    commit = source_commit() or "(not a git checkout)"
    path = out_dir / "commits.txt"
    lines = path.read_text().splitlines() if path.is_file() else []
    if not lines or lines[-1] != commit:
        with open(path, "a") as f:
            f.write(commit + "\n")


_FAILED = "sweep_error"


def _guarded(worker: Callable[[dict], dict], task: dict) -> dict:
    """``worker(task)``, or a failure record if it raised (in the worker's own process, so the
    traceback survives pickling). A worker told to stop (the pool's SIGTERM when the sweep is
    stopped) exits quietly, its task left to run again."""
    import multiprocessing

    from mog_drake.errors import Terminated, terminating

    try:
        return worker(task)
    except Terminated as e:
        if multiprocessing.parent_process() is None:
            raise  # the sweep's own process (--jobs 1): the CLI reports it and exits 143
        raise SystemExit(e.exit_code) from None
    except Exception as e:
        terminating()  # whatever a stop signal left behind is no result
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

        # The pool's semaphores are freed by multiprocessing's resource tracker (a process of
        # its own) if this one is killed outright; it then warns about them on our stderr.
        # Nothing is lost: the warning goes, not the cleanup.
        quiet = "ignore::UserWarning:multiprocessing.resource_tracker"
        if quiet not in os.environ.get("PYTHONWARNINGS", ""):
            os.environ["PYTHONWARNINGS"] = ",".join(filter(None, (os.environ.get("PYTHONWARNINGS"), quiet)))
        # spawn: fresh interpreters, nothing of the parent's Drake state is shared.
        with mp.get_context("spawn").Pool(
            jobs, initializer=_die_with_parent, initargs=(os.getpid(),)
        ) as pool:
            yield from pool.imap_unordered(functools.partial(_guarded, worker), tasks, chunksize=1)


def _die_with_parent(parent: int) -> None:
    """In a worker: exit as soon as the parent process is gone, even if it was SIGKILLed (then
    it cannot stop its pool). Linux delivers a signal on the parent's death (PR_SET_PDEATHSIG);
    elsewhere a watchdog thread sees the worker re-parented."""
    import signal
    import threading
    import time

    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:  # died before the signal was armed
        os._exit(1)

    def watch():
        while True:
            if os.getppid() != parent:
                os._exit(1)
            time.sleep(0.5)

    threading.Thread(target=watch, daemon=True).start()


def _execute_ray(tasks: list[dict], worker, address: str):
    import ray  # connected (`cluster.connect`) before the sweep began

    remote = ray.remote(_guarded)
    pending = [remote.remote(worker, t) for t in tasks]
    while pending:
        ready, pending = ray.wait(pending, num_returns=1)
        yield ray.get(ready[0])
