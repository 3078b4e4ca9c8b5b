"""``python -m circuitsim`` runs the same command line as ``circuitsim``."""

import sys

from circuitsim.cli import main

sys.exit(main())
