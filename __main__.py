"""``python -m platebench``: the command line (same as the ``platebench`` script)."""
import sys

from platebench.bench.cli.main import main

sys.exit(main())
