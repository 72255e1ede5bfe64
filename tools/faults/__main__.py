"""``python -m tools.faults``: run the fault-injection harness (``bad_inputs.main``)."""
import sys

from tools.faults.bad_inputs import main

sys.exit(main())
