"""What every script does first when run: benchmarks/_project.py's check, so that a Python
without the project says so in one line (exit status 2) instead of a traceback."""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir,
                                "benchmarks"))
from _project import require_project  # noqa: E402

del sys.path[0]
require_project()
