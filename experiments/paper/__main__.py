"""``python -m experiments.paper``: see :mod:`experiments.paper.cli`."""

import sys

from experiments.paper.cli import main

sys.exit(main())
