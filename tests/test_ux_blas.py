"""BLAS threads through threadpoolctl: the limit reaches a library loaded before it was set."""

from __future__ import annotations

import json
import subprocess
import sys


def test_single_threaded_blas_after_numpy_is_loaded():
    code = (
        "import os\n"
        "for v in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):\n"
        "    os.environ.pop(v, None)\n"
        "import numpy\n"  # loaded first: environment variables come too late for it
        "from threadpoolctl import threadpool_info\n"
        "before = [p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']\n"
        "from bondid.blas import prefer_single_threaded_blas\n"
        "prefer_single_threaded_blas()\n"
        "after = [p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']\n"
        "import json\n"
        "print(json.dumps([before, after, os.environ['OPENBLAS_NUM_THREADS']]))\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if not k.endswith("_NUM_THREADS")}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    before, after, var = json.loads(proc.stdout)
    assert before and after == [1] * len(before) and var == "1"


def test_a_users_thread_setting_wins():
    code = (
        "import os\n"
        "os.environ['OMP_NUM_THREADS'] = '2'\n"
        "from bondid.blas import prefer_single_threaded_blas\n"
        "prefer_single_threaded_blas()\n"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'))\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if not k.endswith("_NUM_THREADS")}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120)  # fmt: skip
    assert proc.stdout.strip() == "None"
