"""``python -m bondid.diagnose --model URDF --data FILE... [options]``: see :mod:`.cli`."""

import os
import sys

# single-threaded BLAS before numpy loads: the work is many small solves, run in 2 processes
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from .cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
