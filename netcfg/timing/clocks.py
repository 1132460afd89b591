"""Node clocks: every node counts time on its own oscillator, within +-tolerance of nominal.

A sender's period of T ns is T ticks of its own clock; in real time it lasts between T(1 - tol) and T(1 + tol)
(a crystal is typically within +-50..100 ppm; the simulator draws each node's drift within +-50 ppm). An
analysis in real time therefore counts another node's releases in a window of x real nanoseconds as if the window
were `longest_local(x)` = ceil(x / (1 - tol)) ns of the sender's clock, and takes a span of L ns of the sender's
clock (q periods of one message) as at least `shortest_real(L)` = L - ceil(L tol) and at most
`longest_real(L)` = L + ceil(L tol) real ns. All are exact integer arithmetic and work elementwise on numpy
int64 arrays: ceil(x * ppm / d) is taken as (x // d) * ppm + ceil((x % d) * ppm / d), so no product exceeds x
or d * ppm (10^10), whatever the window.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:  # the arithmetic below works on arrays without numpy imported: resolve never loads it
    import numpy as np

PPM = 1_000_000
DEFAULT_TOLERANCE_PPM = 100  # node clocks run within +-100 ppm of nominal unless the bus says otherwise

Ns = TypeVar("Ns", int, "np.ndarray")


def _ceil_scaled(x: Ns, ppm: int, d: int) -> Ns:
    """ceil(x * ppm / d) for x >= 0 without forming x * ppm (an int64 array would overflow past 2^63)."""
    return (x // d) * ppm + -(-((x % d) * ppm) // d)


def longest_local(x: Ns, ppm: int) -> Ns:
    """The most time a clock within +-ppm can count while x ns pass in real time: ceil(x / (1 - ppm/1e6))."""
    if ppm == 0:
        return x
    return x + _ceil_scaled(x, ppm, PPM - ppm)


def longest_real(span: Ns, ppm: int) -> Ns:
    """The most real time in which a clock within +-ppm counts `span` ns: span + ceil(span * ppm/1e6)."""
    if ppm == 0:
        return span
    return span + _ceil_scaled(span, ppm, PPM)


def shortest_real(span: Ns, ppm: int) -> Ns:
    """The least real time in which a clock within +-ppm counts `span` ns: span - ceil(span * ppm/1e6)."""
    if ppm == 0:
        return span
    return span - _ceil_scaled(span, ppm, PPM)
