"""``actuator_crosstalk``: cross-talk between inputs, an input mixing matrix near identity.

A drive whose force is not quite along its own axis (a linear motor's magnet track turned
against the guide, a shaker or a stinger off square), a coil that also pushes on a
neighbouring stage's magnets, or electrical cross-talk between two amplifiers' commands: the
command of one input then also drives another, by a small share. To first order that is

    H' = H (I + F),

``F`` with small off-diagonal entries ``F[a, b]`` (the share of input ``b``'s command that
drives input ``a``): the response in column ``b`` gains ``F[a, b]`` times column ``a``, so a
cross channel leaks in proportion to the row's direct channel, where a sensor misalignment
(:mod:`.sensor_misalignment`, ``(I + E) H``) leaks in proportion to the column's. An FRF
modifier that mixes the columns (:meth:`~.base.Effect.mixing`), no elementwise factor.

Candidates (:mod:`.channel_mixing`): every pair of inputs of one kind (two forces or two
torques; location ``"a,b"`` in input order, parameters ``F[a, b]`` and ``F[b, a]``, named
``f_a_b``), and every such entry together (location ``"all"``).
"""

from __future__ import annotations

from . import register
from .channel_mixing import ChannelMixing


@register
class ActuatorCrosstalk(ChannelMixing):
    name = "actuator_crosstalk"
    description = "cross-talk between inputs: an input mixing matrix near I"
    side = "inputs"
    prefix = "f"
