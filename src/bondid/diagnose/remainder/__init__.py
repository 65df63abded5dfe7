"""What the remainder looks like: from the residual of the best model against the measured
data, what is still missing, in the words of a mechatronics engineer, each finding with the
figures that support it (:func:`describe_remainder` → :class:`Remainder`).

The residual is the complex log error ``e = ln(H_meas / H_model)`` of every used point,
weighed by the points' information weights and judged against the noise each point carries
(:mod:`.residual`). The search (:mod:`.explain`) fits a few parameters of each simple form
the remainder may take, claims the one that removes the most of it when it is significant
against the noise and explains at least ``Settings.min_share`` of the excess, applies it, and
repeats. The forms (one module each):

=====================  =====================================================================
kind                   form and figures
=====================  =====================================================================
``missing_mode``       a mode the model lacks (:mod:`.modes`: a mode term in every channel;
                       :mod:`.lag`: a resonance multiplying one output row or input column):
                       ``f_hz``, ``zeta``, the channels / rows / columns that show it, the
                       MAC to the nearest model mode
``misplaced_mode``     a mode both have, at another frequency or damping in the data
``damping_law``        the paired modes' damping read as one law, when modes are damped
                       otherwise in the data at their own frequencies: ``f_hz``, ``zeta``,
                       ``zeta_model``, ``off`` per mode, the exponent of ``ζ ∝ f^b``
                       (``exponent``, ``exponent_model``), ``law`` and the ``--damping`` kind
                       that expresses it (:mod:`.damping_law`; a summary of the misplaced
                       modes claimed: its share is theirs, it is never ``primary``)
``spurious_mode``      a model mode the data do not show (``scale``: the share they keep)
``confined``           the excess confined to one output row (sensor side), input column
                       (actuator side) or channel: its share against the even share
                       (:mod:`.location`)
``stiffness_offset``   a spring (and damper) to ground in parallel with a drive, or
``mass_offset``        a mass moving with it: ``stiffness`` [N/m], ``damping`` [N·s/m],
                       ``mass`` [kg] (:mod:`.drive`)
``delay``              phase falling linearly with frequency on a row, column or every
                       channel: ``tau_s`` and its std (:mod:`.delay`)
``lag``                a first-order lag (``time_s``, ``f_c_hz``) or a damped second-order
                       roll-off (``f_c_hz``, ``zeta``) on a row, column or every channel
``leakage``            one output reading ``epsilon`` of another (sensor misalignment,
                       cross-talk), or one input driving through another (:mod:`.leakage`)
``gain_offset``        a constant dB offset of a row or column (calibration): ``gain_db``,
                       ``reversed`` (the sign flipped: wrong polarity)
``gain_slope``         a gain growing as a power ``alpha`` of frequency (with its phase): a
                       quantity taken for another (velocity for displacement), a sensitivity
                       that changes with frequency (:mod:`.slope`)
``notch``              a dip at ``f_hz`` (``depth_db``, ``zeta``) in one row or column only: a
                       notch filter, an anti-resonance the model lacks (:mod:`.notch`)
=====================  =====================================================================

**JSON** (:meth:`Remainder.as_dict`, the ``remainder`` of ``diagnosis.json``)::

    {
      "primary": {"kind": str | null, "side": str, "names": [str],
                  "bands_hz": [[f_lo, f_hi], ...]},   # Remainder.primary()
      "excess": {
        "db_rms": float,          # weighted RMS log error of the model [dB]
        "noise_db": float,        # the level an exact model would show [dB]
        "ratio": float, "n_eff": float, "above_noise": bool,
        "by_channel": {"OUT.IN": PART, ...}, "by_output": {"OUT": PART, ...},
        "by_input": {"IN": PART, ...},
        "by_band": [{"f_lo_hz", "f_hi_hz", **PART}, ...],        # fixed log bands
        "where": {"bands": [{"f_lo_hz", "f_hi_hz", **PART}, ...],  # carrying 60 %
                  "channels": ["OUT.IN", ...]}
      },
      # PART = {"db_rms", "noise_db", "share" (of the excess), "even_share" (of the
      #         weight), "z" (how far above the noise), "above_noise"}
      "after": {"db_rms", "noise_db", "above_noise"},   # with every cause corrected
      "explained_share": float,   # of the excess over the noise, by the causes together
      # every share is taken against the excess where it lies: the positive parts of the
      # excess of each channel in each fixed band (excess.positive_excess)
      "findings": [               # largest share first
        {"kind": str, "text": str, "share": float, "advice": str,
         "location": {"side": "output|input|channel|drive|global", "names": [str],
                      "channels": [str]},
         "band_hz": [f_lo, f_hi] | null,
         "significance": {"reduction_db2", "share", "statistic", "dof", "p_value",
                          "p_threshold", "n_params", "significant"} | null,
         "figures": {...},        # by kind, as in the table above
         "alternatives": [str]},  # descriptions the data cannot tell from this one
        ...
      ],
      "summary": [str],           # Remainder.sentences()
      "notes": [str],
      "settings": {...}
    }
"""

from __future__ import annotations

from .base import KINDS, Finding, Location, Significance
from .context import Settings
from .describe import Remainder, describe_remainder

__all__ = [
    "KINDS",
    "Finding",
    "Location",
    "Remainder",
    "Settings",
    "Significance",
    "describe_remainder",
]
