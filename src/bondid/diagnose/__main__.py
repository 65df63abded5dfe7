"""``python -m bondid.diagnose --model URDF --data FILE... [options]``: see :mod:`.cli`."""

from ..blas import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before numpy loads: many small solves, run in 2 processes

from .cli import main  # noqa: E402

if __name__ == "__main__":
    from ..interrupt import exit_process

    exit_process(main())
