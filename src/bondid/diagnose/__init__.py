"""Diagnosis of the sim-to-real gap: where it lies, which unmodelled effect causes it, how far
it shrinks (``python -m bondid.diagnose``).

Public API (imported lazily, so ``import bondid.diagnose`` stays cheap):

* :func:`diagnose` (:mod:`.pipeline`) → :class:`Diagnosis`; :class:`Settings`;
* :func:`write_outputs`, :func:`summary`, :func:`to_json_dict` (:mod:`.report`);
* the effect library :mod:`.effects` (:class:`~.effects.base.Effect`, ``register``);
* the gap: :mod:`.gap`; the modes of the data and of the model come from :mod:`bondid.modal`.
"""

from __future__ import annotations

from ..lazy import lazy_getattr

_LAZY = {
    "diagnose": "pipeline",
    "Diagnosis": "pipeline",
    "Settings": "pipeline",
    "write_outputs": "report",
    "summary": "report",
    "to_json_dict": "report",
}

__all__ = sorted(_LAZY)

__getattr__ = lazy_getattr(__name__, _LAZY)
