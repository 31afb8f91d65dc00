"""The project's exception types: errors a user can cause, and faults of the real robot."""

from __future__ import annotations


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
