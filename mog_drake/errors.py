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


@contextlib.contextmanager
def stop_on_signals():
    """Within the block, SIGTERM and SIGHUP raise `Terminated` in the main thread (on any
    other thread, or where signals cannot be set, it does nothing). The handlers it replaced
    come back when the block ends; blocks nest."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    arrived = []

    def handler(signum, frame):
        if arrived:  # a second signal must not cut short the cleanup the first one started
            return
        arrived.append(signum)
        raise Terminated(signum)

    saved = {}
    try:
        for s in (signal.SIGTERM, signal.SIGHUP):
            saved[s] = signal.signal(s, handler)
        yield
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
