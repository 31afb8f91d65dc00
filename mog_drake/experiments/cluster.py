"""A sweep's tasks on a Ray cluster (``--ray ADDRESS``): the connection, checked in bounded time
before anything runs, and the package sent along with the tasks.

Ray's own ``ray.init(address)`` retries a cluster that does not answer for minutes (its GCS
client every 5-30 s), and its messages name its own flags. So the address is checked here
first: its form, then a TCP connection (5 s), then a trial ``ray.init`` in a child process
(killed after ``CONNECT_TIMEOUT_S``), each refusal one line naming the address. The sweep's
own ``ray.init`` sends this package's source with the tasks (``runtime_env`` ``py_modules``):
each node needs only the dependencies (drake, numpy, shapely, scipy, matplotlib, PyYAML) in
the Python that runs Ray, not a checkout of its own.
"""

from __future__ import annotations

import multiprocessing as mp
import socket
from pathlib import Path

from mog_drake.errors import MogError

CONNECT_TIMEOUT_S = 12.0  # the trial connection, after the TCP check (s)
TCP_TIMEOUT_S = 5.0


def _ray():
    try:
        import ray
    except ImportError:
        raise MogError("--ray needs Ray: pip install 'mog_drake[ray]'") from None
    return ray


def check_address(address: str) -> tuple[str, int] | None:
    """(host, port) of a ``HOST:PORT`` address (``ray://`` allowed), None for ``auto``; one line
    for anything else."""
    if address == "auto":
        return None
    text = address.removeprefix("ray://")
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise MogError(
            f"--ray {address}: not a Ray cluster's address (auto, or HOST:PORT as `ray start --head` prints it, "
            "e.g. 127.0.0.1:6379)"
        )
    return host.strip("[]"), int(port)


def _trial(address: str, answer) -> None:
    """In a child process: connect, report, disconnect (Ray's own log lines kept off the
    terminal: the parent says in one line what went wrong)."""
    import os

    os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
    try:
        ray = _ray()
        ray.init(address=address, log_to_driver=False, logging_level="ERROR")
        answer.put("")
        ray.shutdown()
    except Exception as e:  # any refusal, reported in one line by the parent
        answer.put(" ".join(str(e).split())[:200] or type(e).__name__)


def connect(address: str) -> None:
    """Connects this process to the Ray cluster at ``address``, its tasks carrying this
    package's source; one `MogError` line if no cluster answers there in bounded time."""
    ray = _ray()
    hostport = check_address(address)
    if hostport is not None:
        try:
            socket.create_connection(hostport, timeout=TCP_TIMEOUT_S).close()
        except OSError as e:
            raise MogError(
                f"--ray {address}: no Ray cluster answers there ({e.strerror or type(e).__name__}); "
                "start one with `ray start --head` and give the address it prints"
            ) from None
    ctx = mp.get_context("spawn")
    answer = ctx.Queue()
    trial = ctx.Process(target=_trial, args=(address, answer), daemon=True)
    trial.start()
    trial.join(CONNECT_TIMEOUT_S)
    if trial.is_alive():
        trial.kill()
        trial.join()
        raise MogError(
            f"--ray {address}: no Ray cluster answered within {CONNECT_TIMEOUT_S:g} s (something else listens "
            "there? the dashboard's port is not the cluster's)"
        )
    why = answer.get() if not answer.empty() else "the trial connection ended without a word"
    if why:
        if address == "auto":
            raise MogError("--ray auto: no Ray cluster runs on this machine (start one: `ray start --head`)")
        raise MogError(f"--ray {address}: {why}")
    ray.init(
        address=address,
        ignore_reinit_error=True,
        log_to_driver=False,
        logging_level="ERROR",
        runtime_env={"py_modules": [str(_package())]},
    )


def _package() -> Path:
    """The folder of this package's source, its models inside it (``mog_drake/models``, as
    the wheel lays them out): the installed package itself, or, from a checkout (the models
    at its top level), a copy staged in a temporary folder for the life of this process."""
    import atexit
    import shutil
    import tempfile

    import mog_drake
    from mog_drake.files import model_path

    package = Path(mog_drake.__file__).resolve().parent
    models = model_path("shapes.yaml").resolve().parent
    if models == package / "models":
        return package
    stage = Path(tempfile.mkdtemp(prefix="mog_drake_ray_"))
    atexit.register(shutil.rmtree, stage, ignore_errors=True)
    shutil.copytree(package, stage / "mog_drake", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(models, stage / "mog_drake" / "models")
    return stage / "mog_drake"
