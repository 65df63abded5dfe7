"""The physical ranges bondid accepts, in one place (SI units, frequencies in Hz).

A value outside is not a machine any instrument measured: a typing or unit error, or a file
made to break the tool (unchecked, a spring of 1e300 runs and is reported as a "negative
stiffness" after round-off, and a mass of 1e-300 is fitted). Each is refused before any work
with the item and the range.
The ranges are wide on purpose: from a MEMS part to a machine tool's bed, from a flexure to
a rigid coupling.

Also here: the structural limits of a model file, checked before it is parsed deeply (a URDF
of 200,000 nested elements crashes the process in a recursive copy; a chain of 3,000 links
exhausts Python's recursion).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Range:
    """A closed range ``[lo, hi]`` of a quantity, with its unit for messages."""

    what: str
    lo: float
    hi: float
    unit: str

    def __contains__(self, value: object) -> bool:
        try:
            v = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return False
        return math.isfinite(v) and self.lo <= v <= self.hi

    def text(self) -> str:
        """``"a mass from 1e-09 to 1e+09 kg"``."""
        return f"{self.what} from {self.lo:g} to {self.hi:g} {self.unit}".rstrip()


#: the mass of a body (a link with an ``<inertial>``): a bond wire's capillary to a bridge
MASS = Range("a mass", 1e-9, 1e9, "kg")
#: a principal moment of inertia (0: a point mass)
INERTIA = Range("a moment of inertia", 0.0, 1e12, "kg·m²")
#: any length or coordinate: joint and CoM origins, box sizes, radii
LENGTH = Range("a coordinate", -1e4, 1e4, "m")
#: an angle of an ``rpy`` origin
ANGLE = Range("an angle", -1e3, 1e3, "rad")
#: a joint spring (translational N/m or rotational N·m/rad)
STIFFNESS = Range("a stiffness", 0.0, 1e15, "N/m or N·m/rad")
#: a joint damper (N·s/m or N·m·s/rad)
DAMPING = Range("a damping", 0.0, 1e12, "N·s/m or N·m·s/rad")
#: a joint limit or an operating-point coordinate (m or rad)
POSITION = Range("a position", -1e4, 1e4, "m or rad")
#: a frequency line of a measurement or of a command's grid
FREQUENCY = Range("a frequency", 0.0, 1e6, "Hz")

#: deepest nesting of XML elements in a URDF (a real one nests 5 or 6 deep)
MAX_XML_DEPTH = 100
#: most XML elements in a URDF (a large machine has a few thousand)
MAX_XML_ELEMENTS = 1_000_000
#: longest chain of links from the root (a real machine has tens)
MAX_CHAIN_DEPTH = 500
