"""``python -m controllers.grasp``: see :mod:`controllers.grasp.cli`."""

import sys

from controllers.grasp.cli import main

sys.exit(main())
