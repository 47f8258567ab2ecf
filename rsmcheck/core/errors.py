"""Error types shared by every part of rsmcheck.

`InputError` is raised for anything a user wrote wrongly (a case file, a parameter
override, a command-line argument).  The command line turns it into one line on stderr
and exit code 2.  `SimulationDiverged` is raised by an engine whose state stopped being
finite or bounded; it carries the time, the phase and the quantity that blew up.
"""

from __future__ import annotations

import os
import sys
from typing import Callable


class InputError(ValueError):
    """Bad user input: `where` names the file (or source) and `field` the key."""

    def __init__(self, where: str, field: str, reason: str):
        self.where = where
        self.field = field
        self.reason = reason
        super().__init__(f"{where}: {field}: {reason}")

    def __reduce__(self):
        # rebuilt from the constructor's arguments (the default pickles `args`, one string)
        return (type(self), (self.where, self.field, self.reason))


class SimulationDiverged(RuntimeError):
    """A simulation left the range where its results mean anything."""

    def __init__(self, engine: str, time: float, phase: str, quantity: str, value: float):
        self.engine = engine
        self.time = time
        self.phase = phase
        self.quantity = quantity
        self.value = value
        super().__init__(
            f"{engine}: diverged at t = {time:.6g} s in phase '{phase}': "
            f"{quantity} = {value:.6g}"
        )

    def __reduce__(self):
        return (type(self), (self.engine, self.time, self.phase, self.quantity, self.value))


def quiet_stdout() -> None:
    """After a broken pipe: point the standard output (and error) at the null device, so
    that what is still buffered and the interpreter's last flush at exit cannot fail
    again ("Exception ignored ... BrokenPipeError", exit status 120).  The Python
    documentation's recipe (signal module, note on SIGPIPE)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    for stream in (sys.stdout, sys.stderr):
        try:
            os.dup2(devnull, stream.fileno())
        except (OSError, ValueError, AttributeError):  # no file descriptor (a test's capture)
            pass
    os.close(devnull)


def flush_stdout() -> bool:
    """Flush the standard output; False (and `quiet_stdout`) if its reader went away."""
    try:
        sys.stdout.flush()
        return True
    except BrokenPipeError:
        quiet_stdout()
        return False


def exit_code(prog: str, action: Callable[[], int], cut_short: int = 1) -> int:
    """Run a command's `action` and return its exit code; a bad input is one line on stderr
    and 2, a diverged simulation one line and 1, an interrupt 130 (no traceback).

    When the reader of the standard output goes away (`rsmcheck cases | head -1`) the
    command ends quietly: nothing on stderr, the command's own code if it had finished,
    else `cut_short` (1: its work was not all done and not all shown; 0 for a listing)."""
    code: int | None = None
    try:
        code = action()
        sys.stdout.flush()  # a reader that left shows here when the output was buffered
        return code
    except InputError as exc:
        sys.stderr.write(f"{prog}: {exc}\n")
        return 2
    except SimulationDiverged as exc:
        sys.stderr.write(f"{prog}: {exc}\n")
        return 1
    except KeyboardInterrupt:
        sys.stderr.write(f"{prog}: interrupted\n")
        return 130
    except BrokenPipeError:  # the reader went away: not an error of ours
        quiet_stdout()
        return code if code is not None else cut_short
    except SystemExit:  # a command's own argument parser: --help, or a usage error
        flush_stdout()
        raise
