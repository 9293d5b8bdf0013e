"""``python -m suspension_estimation.harness run <scenario>`` and ``python -m suspension_estimation.harness paper``: see harness/cli.py."""
import os

# One thread per process for the numerical libraries, before numpy loads: the paper study runs in
# parallel worker processes (spawned: they re-import this module), which are the parallelism.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import sys  # noqa: E402

from .cli import main  # noqa: E402

if __name__ == "__main__":
    code = main()
    # Leave without the C-level exit handlers of the pythonfmu binaries loaded in this process:
    # their destructor can touch the finalized interpreter and abort after the results are
    # written (PythonFMU issue 229). Everything is flushed first.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
