"""``python -m rasm.cli``: the ``rasm`` command."""

import sys

from rasm.cli.commands import main

sys.exit(main())
