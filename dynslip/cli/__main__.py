"""``python -m dynslip.cli``: the ``dynslip`` command."""

import sys

from dynslip.cli import main

sys.exit(main())
