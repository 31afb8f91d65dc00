"""The project's exception types: errors a user can cause, and faults of the real robot."""

from __future__ import annotations

import contextlib


class MogError(Exception):
    """A user-caused error (bad file, unknown shape, invalid pose, unreachable grasp, ...).

    The message names the offending item; the CLI prints it on one line and exits 2.
    """

    exit_code = 2


class HardwareFault(MogError):
    """The arm or the gripper reported a fault, refused a command, or stopped answering.

    The message starts with the device (``UR5: ...`` or ``gripper: ...``); the CLI prints it on
    one line and exits 3, so a script can tell a hardware fault from a user error (exit 2).
    """

    exit_code = 3


class StationFault(MogError):
    """The simulated station's physics failed (a non-finite state, the contact solver did not
    converge). The message names the time and the body; ``run`` is the record of what the run
    did until then and ``path`` the file the station's last finite state was saved to. The
    CLI prints the record, then the one line, and exits 3."""

    exit_code = 3

    def __init__(self, message: str, run=None, path=None):
        super().__init__(message)
        self.run, self.path = run, path


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived (`kill`, systemd, a container runtime, a closed terminal).

    Raised in the main thread by `stop_on_signals`, like KeyboardInterrupt for SIGINT, so that
    every ``finally`` on the way out runs: the hardware station stops the arm and closes its
    connections, a sweep keeps what it wrote. The CLI exits 128 + the signal's number."""

    def __init__(self, signum: int):
        import signal

        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


# The stop signal that arrived (SIGTERM or SIGHUP) within the outermost `stop_on_signals`
# block: from then on the process is on its way out, and nothing may take it for anything else.
_arrived: list[int] = []
_depth = [0]


def terminating() -> None:
    """Raises `Terminated` if a stop signal has arrived. Every ``except Exception`` that could
    catch what a signal left behind calls it first: a signal raised inside a Drake callback
    comes back out of the C++ layer as some other exception (seen: a ``TypeError`` from
    ``SetFromVector``), which a broad handler would take for a physics error and store as a
    result."""
    if _arrived:
        raise Terminated(_arrived[0])


@contextlib.contextmanager
def stop_on_signals():
    """Within the block, SIGTERM and SIGHUP raise `Terminated` in the main thread (on any
    other thread, or where signals cannot be set, it does nothing). Blocks nest; a signal is
    raised once, however deep: a second one, while the first one's cleanup runs, is ignored.
    The handlers the block replaced come back when it ends (`ignore_stop_signals` keeps a
    stopping process from being killed after that)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        if _arrived:  # the stop is under way
            return
        _arrived.append(signum)
        raise Terminated(signum)

    if _depth[0] == 0:
        _arrived.clear()
    saved = {}
    _depth[0] += 1
    try:
        for s in (signal.SIGTERM, signal.SIGHUP):
            saved[s] = signal.signal(s, handler)
        yield
    finally:
        _depth[0] -= 1
        for s, h in saved.items():
            signal.signal(s, h)


def ignore_stop_signals() -> None:
    """SIGTERM and SIGHUP ignored from now on: for a process that is stopping on the first
    one (its exit code already decided: 128 + that signal), while its last threads and
    destructors finish."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        for s in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(s, signal.SIG_IGN)
