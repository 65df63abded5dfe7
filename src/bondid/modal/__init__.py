"""Modal identification: the modes in a measured FRF, the modes of a model, and how the two
pair up.

* :mod:`.identify` — :func:`~.identify.identify_modes` (poles and residues of a measured
  FRF, band by band) and :func:`~.identify.model_modes` (the same description of a linear
  model's vibration modes);
* :mod:`.lscf` — the estimators: poly-reference LSCF, stabilisation, LSFD;
* :mod:`.pairing` — paired / missing / spurious modes, by frequency and MAC;
* :mod:`.antiresonance` — drive-point anti-resonances and their shifts;
* :mod:`.record` — :class:`~.record.IdentifiedMode`, the record of one mode.

The layer sits on the data and the linear model, below the diagnosis, which places its
structural candidates at the measured modes and describes the remainder by them.
"""
