"""``python -m bidegree``: the command line (see :mod:`bidegree.cli`)."""

import sys

from bidegree.cli import main

sys.exit(main())
