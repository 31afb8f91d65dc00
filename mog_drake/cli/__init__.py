"""The `mog-drake` command line. Thin: parse, call, print.

Each area's commands and their arguments live in a module of their own (`geometry`,
`experiments`, `robot`); what they share in `common`. A user error prints one line
`mog-drake: error: ...` and exits 2, with no traceback.
"""

from __future__ import annotations

import contextlib
import sys

from mog_drake.cli import calibrate, experiments, geometry, robot
from mog_drake.cli.common import Parser, UsageError, check_args
from mog_drake.errors import MogError, Terminated, ignore_stop_signals, stop_on_signals


def build_parser() -> Parser:
    p = Parser(prog="mog-drake", description="Multi-object push-grasping in the plane, on Drake.")
    sub = p.add_subparsers(dest="command", required=True)
    geometry.add_parsers(sub)
    experiments.add_parsers(sub)
    robot.add_parsers(sub)
    calibrate.add_parsers(sub)
    return p


@contextlib.contextmanager
def _one_line_warnings():
    """Within the block a warning is one line on stderr, ``mog-drake: warning: ...``, and
    numpy's RuntimeWarnings (a mean of nothing, 0 / 0) are not shown: their NaN is in the
    table already."""
    import warnings

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"mog-drake: warning: {' '.join(str(message).split())}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.showwarning = show
        yield


def main(argv: list[str] | None = None) -> int:
    try:
        with stop_on_signals(), _one_line_warnings():
            args = build_parser().parse_args(argv)
            check_args(args)
            return int(args.func(args) or 0)
    except UsageError as e:
        print(f"mog-drake: error: {e}", file=sys.stderr)
        return 2
    except MogError as e:  # HardwareFault included: exit 3
        print(f"mog-drake: error: {' '.join(str(e).split())}", file=sys.stderr)
        return e.exit_code
    except BrokenPipeError:  # the reader went away (`mog-drake shapes | head`): as any Unix tool
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing more to flush there
        return 141  # 128 + SIGPIPE, what a shell reports for `yes | head`
    except OSError as e:  # a path that cannot be written or read (permissions, a full disk)
        where = f": {e.filename}" if getattr(e, "filename", None) else ""
        print(f"mog-drake: error: {e.strerror or e}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mog-drake: interrupted", file=sys.stderr)
        return 130
    except Terminated as e:
        ignore_stop_signals()  # a second signal must not kill the process before it exits
        print(f"mog-drake: terminated by {e}", file=sys.stderr)
        return e.exit_code


if __name__ == "__main__":
    sys.exit(main())
