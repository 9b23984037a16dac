"""`python -m gcs_swarm` == the `gcs-swarm` command."""

import sys

from gcs_swarm.cli import main

sys.exit(main())
