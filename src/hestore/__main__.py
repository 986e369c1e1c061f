"""``python -m hestore``: the same as the ``hestore`` command."""

import sys

try:
    from hestore.cli import main
except KeyboardInterrupt:  # Ctrl-C before the command even started: nothing to undo, nothing to say
    sys.exit(130)

sys.exit(main())
