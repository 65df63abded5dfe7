"""``python -m bondid.fit``: see :mod:`bondid.fit.cli`."""

from __future__ import annotations

from ..blas import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before numpy loads (see bondid.blas)

from .cli import main  # noqa: E402

if __name__ == "__main__":
    from ..interrupt import exit_process

    exit_process(main())
