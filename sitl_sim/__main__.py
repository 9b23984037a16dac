"""`python -m sitl_sim` == the `sitl-sim` command."""

import sys

from sitl_sim.cli import main

sys.exit(main())
