"""``python tools/faults/run.py``: the fault-injection harness (the same as ``python -m tools.faults``),
runnable by path from any folder: it puts the repository root on the import path."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tools.faults.bad_inputs import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
