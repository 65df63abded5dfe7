"""``sensor_misalignment``: cross-talk between outputs, an output mixing matrix near identity.

A sensor whose measuring direction is turned by a small angle α toward another measured
direction reads ``cos α`` of its own motion plus ``sin α`` of the other (an interferometer or a
scale not square to its axis, a tilted accelerometer), and electrical cross-talk between two
channels adds a share of one to the other alike. To first order that is

    H' = (I + E) H,

``E`` with small off-diagonal entries ``E[a, b]`` (how much of output ``b`` appears in output
``a``): the leakage into a cross channel is proportional to a direct one. An FRF modifier that
mixes the rows (:meth:`~.base.Effect.mixing`), no elementwise factor.

Candidates (:mod:`.channel_mixing`): every pair of sensors that measure the same kind of
quantity (location ``"a,b"`` in output order, parameters ``E[a, b]`` and ``E[b, a]``, named
``e_a_b``), and every such entry together (location ``"all"``).
"""

from __future__ import annotations

from . import register
from .channel_mixing import ChannelMixing


@register
class SensorMisalignment(ChannelMixing):
    name = "sensor_misalignment"
    description = "cross-talk / misalignment between outputs: an output mixing matrix near I"
    side = "outputs"
    prefix = "e"
