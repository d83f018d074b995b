"""``python -m rasm.cli``: the ``rasm`` command."""

import sys

from rasm.cli.main import main

sys.exit(main())
