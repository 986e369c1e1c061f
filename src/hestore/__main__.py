"""``python -m hestore``: the same as the ``hestore`` command."""

import sys

from hestore.cli import main

sys.exit(main())
