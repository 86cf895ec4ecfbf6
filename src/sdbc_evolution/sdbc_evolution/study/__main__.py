"""``python -m sdbc_evolution.study``: the same as ``sdbc-study``."""

import sys

from sdbc_evolution.study.cli import main

sys.exit(main())
