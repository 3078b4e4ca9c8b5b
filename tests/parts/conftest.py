"""The part-library tests: their bench helpers (partbench.py) sit beside them."""

import sys
from pathlib import Path

# The tests folder is not a package; make ``import partbench`` work however pytest is started.
sys.path.insert(0, str(Path(__file__).parent))
