"""``python -m couture``: the same command line as the ``couture`` script."""

import sys

from couture.cli import main

sys.exit(main())
