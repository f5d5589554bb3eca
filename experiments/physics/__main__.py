"""``python -m experiments.physics``: see :mod:`experiments.physics.cli`."""

import sys

from experiments.physics.cli import main

sys.exit(main())
