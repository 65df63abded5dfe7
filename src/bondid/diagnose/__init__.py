"""Diagnosis of the sim-to-real gap: where it lies, which unmodelled effect causes it, how far
it shrinks (``python -m bondid.diagnose``).

Public API (imported lazily, so ``import bondid.diagnose`` stays cheap):

* :func:`diagnose` (:mod:`.pipeline`) → :class:`Diagnosis`; :class:`Settings`;
* :func:`write_outputs`, :func:`summary`, :func:`to_json_dict` (:mod:`.report`);
* the effect library :mod:`.effects` (:class:`~.effects.base.Effect`, ``register``);
* gap and modes: :mod:`.gap`, :mod:`.modal_id`.
"""

from __future__ import annotations

from typing import Any

_LAZY = {
    "diagnose": "pipeline",
    "Diagnosis": "pipeline",
    "Settings": "pipeline",
    "write_outputs": "report",
    "summary": "report",
    "to_json_dict": "report",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
