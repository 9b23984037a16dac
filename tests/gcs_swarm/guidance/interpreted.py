"""Run a test's own function as plain Python: in a subprocess with NUMBA_DISABLE_JIT=1 (numba's switch), so
that its arrays can be compared bit for bit with the compiled run of this process."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[3]


def interpreted_arrays(module: str, expression: str, out: Path, timeout_s: float) -> Any:
    """The arrays of `expression` (a dict of name -> array, written with the names `module` (dotted) exports)
    evaluated with every kernel interpreted, from the .npz file `out` (np.load's NpzFile)."""
    script = (
        "import numpy as np, numba, sys\n"
        "assert numba.config.DISABLE_JIT\n"
        f"from {module} import *\n"
        f"np.savez(sys.argv[1], **({expression}))\n"
    )
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    subprocess.run([sys.executable, "-c", script, str(out)], check=True, cwd=ROOT, env=env, timeout=timeout_s)
    return np.load(out)
