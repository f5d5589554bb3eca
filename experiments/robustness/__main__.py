"""``python -m experiments.robustness``: see :mod:`experiments.robustness.cli`."""

import sys

from experiments.robustness.cli import main

sys.exit(main())
