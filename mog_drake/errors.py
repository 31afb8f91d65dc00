"""The one exception type for errors a user can cause."""

from __future__ import annotations


class MogError(Exception):
    """A user-caused error (bad file, unknown shape, invalid pose, unreachable grasp, ...).

    The message names the offending item; the CLI prints it on one line and exits 2.
    """
