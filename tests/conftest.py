"""Test-session setup: single-threaded BLAS (the models are small; threads only contend on
the 2-core CI machine). Set before NumPy is first imported."""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
