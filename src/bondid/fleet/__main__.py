"""``python -m bondid.fleet``: see :mod:`bondid.fleet.cli`."""

from __future__ import annotations

from ..blas import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before numpy loads; local Dask workers inherit it

from .cli import main  # noqa: E402

if __name__ == "__main__":
    from ..interrupt import exit_process

    exit_process(main())
