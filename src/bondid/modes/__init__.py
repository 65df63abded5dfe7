"""Modal analysis of the linearised machine and its mode shapes in Meshcat.

``python -m bondid.modes --model URDF`` prints the mode table and writes ``modes.json`` and a
static, offline ``modes.html`` animation (see :mod:`bondid.modes.__main__`).
"""

from .analysis import ModalResult, Mode, match_mode, modal_analysis

__all__ = ["ModalResult", "Mode", "match_mode", "modal_analysis"]
