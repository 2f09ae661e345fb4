"""``python -m tolerance_ros.cli``: the same as ``tolerance-ros``."""
import sys

from . import entry

sys.exit(entry())
