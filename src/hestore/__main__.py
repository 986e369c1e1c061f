"""The ``hestore`` command's entry point: ``python -m hestore``, and the console script ``hestore`` (`main`).

This module owns Ctrl-C on the command line, from the process's first line
of hestore's code to its last. It is tiny and imports nothing of hestore at
module level, and ``import hestore`` itself loads nothing (`hestore`'s names
are loaded on first use), so that `main` runs before the command line's
imports — SQLAlchemy, numpy and the library, which take a second or two. An
interrupt while they load stops the process at once with one line and exit
status 130: nothing has started, so there is nothing to undo. Once the
command runs (`hestore.cli.main`), an interrupt is the `KeyboardInterrupt`
that rolls its transaction back on the way out, and then the same line and
status.

`main` takes over the process's SIGINT handling: it is for this process's
own entry, not for calling from other code (call `hestore.cli.main`).
"""

import os
import sys

try:
    # The C module itself: ``signal`` first imports enum, functools and collections, several milliseconds in
    # which Ctrl-C would still be a traceback.
    import _signal as signal
except ImportError:  # an interpreter without it
    import signal

#: What an interrupted command says, on stderr, before it exits with `INTERRUPTED_STATUS`.
INTERRUPTED = "hestore: interrupted; the unfinished command changed nothing"

#: The exit status of an interrupted command: 128 + SIGINT, as a shell reports a process Ctrl-C stopped.
INTERRUPTED_STATUS = 130


def _stop(signum, frame) -> None:
    """SIGINT while nothing runs that could be undone: say so and leave at once."""
    try:
        # Not print(): a signal handler may interrupt a write to sys.stderr, which is not reentrant.
        os.write(2, f"{INTERRUPTED}\n".encode())
    except OSError:  # no stderr to say it on: the status still says it
        pass
    os._exit(INTERRUPTED_STATUS)


def main() -> int:
    """Run the command line on ``sys.argv``, interruptible throughout; the exit status."""
    # A process started with SIGINT ignored (a background job of a shell without job control) keeps it ignored.
    ours = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    if ours:
        signal.signal(signal.SIGINT, _stop)
    try:
        from hestore.cli import main as run

        if ours:
            # From here an interrupt unwinds the command: its transaction rolls back on the way out.
            signal.signal(signal.SIGINT, signal.default_int_handler)
        return run()
    except KeyboardInterrupt:
        # Through sys.stderr, after whatever the command left there (a progress bar clearing its line).
        print(INTERRUPTED, file=sys.stderr)
        return INTERRUPTED_STATUS
    finally:
        if ours:
            # The command is over, done or rolled back: an interrupt now only ends the process sooner.
            signal.signal(signal.SIGINT, _stop)


if __name__ == "__main__":
    sys.exit(main())
