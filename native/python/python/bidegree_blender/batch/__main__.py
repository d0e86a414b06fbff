"""``python -m bidegree_blender.batch``."""

import sys

from .cli import main

sys.exit(main())
