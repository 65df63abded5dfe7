"""Blind benchmark of ``python -m bondid.diagnose`` over several machine designs and data regimes.

Modules, one job each:

- :mod:`.designs`  the machine designs (URDF files and their operating points);
- :mod:`.truth`    truth machines: parameter errors and withheld effects (never the diagnosis's
  own candidates);
- :mod:`.regimes`  the measurement regimes (noise, floors, coherence, quantity) and data files;
- :mod:`.cases`    the case list;
- :mod:`.runner`   one case end to end (diagnosis and fit as subprocesses) and its scores;
- :mod:`.tables`   Markdown tables and summaries.

The command line is ``tools/blind_benchmark.py``.
"""
