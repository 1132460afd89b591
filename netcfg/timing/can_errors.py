"""Bit errors on CAN: the sporadic error model, its cost in the response-time analysis, and how likely a bit error
rate is to break it.

Model (Tindell and Burns 1994, "Guaranteeing message latencies on Controller Area Network", ICC; Punnekkat, Hansson
and Norstrom 2000, "Response time analysis under errors for CAN", RTAS): in any window of length t at most

    n + ceil(t / T_err)

errors hit frames (n: a burst that may come at once; then one per T_err). Each costs an error frame and the
retransmission of the frame it hit, so a message m can lose, in a window of length t,

    E_m(t) = (n + ceil(t / T_err)) * (error frame + max over k in hep(m) of C_k)

(hep(m): the messages of priority higher than or equal to m's; a lower-priority frame hit while m waits is not sent
again before m, so its loss is the error frame and the part sent, no more than a whole frame). The error frame is
taken at its longest, 31 bits (Punnekkat et al.): an error flag of 6 bits, up to 6 more while the other nodes
superpose theirs, the 8-bit delimiter, the 3-bit intermission and, for an error-passive transmitter, 8 bits of
suspended transmission.
On CAN FD the error frame is sent at the arbitration (nominal) bit rate: a node that detects an error in the data
phase switches back to the nominal rate to signal it (ISO 11898-1:2015), so 31 nominal bits there too.

Whether the model holds: errors that hit frames are taken as a Poisson process of rate lambda = BER * (bits sent
per second). The model is broken exactly when, for some error i and the k-th error after it (k > n), they are less
than (k - n) * T_err apart (for any window, count the errors in it from its first one). So, by the union bound over
the error i and over m = k - n >= 1,

    P(broken within H) <= lambda * H * sum over m >= 1 of P(Poisson(lambda * m * T_err) >= m + n),

an upper bound, and close to the truth when small (it counts a break once per error that starts it). When
lambda * T_err >= 1 the errors come, on average, faster than the model allows, and the probability is taken as 1.
Without a model (an error-free bus) the probability is that of any error at all: 1 - exp(-lambda * H).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from math import exp, lgamma, log

from netcfg.timing.frames import bits_to_ns

ERROR_FRAME_BITS = 31  # the longest error frame and its recovery, at the nominal bit rate
HOUR_NS = 3_600_000_000_000
MAX_TERMS = 10_000  # of the series over m; it converges geometrically when lambda * T_err < 1


@dataclass(frozen=True)
class ErrorModel:
    burst: int  # n
    interval_ns: int  # T_err
    error_frame_ns: int  # ERROR_FRAME_BITS at the bus's nominal bit rate

    @staticmethod
    def for_bus(burst: int, interval_ns: int, bitrate: int) -> ErrorModel:
        return ErrorModel(burst, interval_ns, bits_to_ns(ERROR_FRAME_BITS, bitrate))

    def errors_in(self, window_ns: int) -> int:
        """The most errors the model allows in a window of this length: n + ceil(t / T_err)."""
        return self.burst + max(0, -(-window_ns // self.interval_ns))

    def overhead(self, window_ns: int, largest_frame_ns: int) -> int:
        """E(t): what those errors cost when the largest frame they can make resend takes largest_frame_ns."""
        return self.errors_in(window_ns) * (self.error_frame_ns + largest_frame_ns)

    @property
    def rate(self) -> tuple[int, int]:
        """(errors per T_err, T_err): the long-run error rate the model allows, 1 per T_err, as a (C, T) load."""
        return 1, self.interval_ns


def describe(burst: int, interval: str) -> str:
    """The model in words, for reports: 'at most 2 errors at once, then one per 10 ms'."""
    if burst == 0:
        return f"at most one error per {interval}"
    return f"at most {burst} error{'s' if burst > 1 else ''} at once, then one per {interval}"


def recovery_costs(c_by_priority: Sequence[int], model: ErrorModel) -> list[int]:
    """Per message, in priority order (highest first): error frame + the largest C at or above its priority."""
    out, largest = [], 0
    for c in c_by_priority:
        largest = max(largest, c)
        out.append(model.error_frame_ns + largest)
    return out


def errors_per_second(ber: float, bitrate: int, utilization: float) -> float:
    """Errors that hit frames: the bit error rate times the bits on the wire (the bus is busy `utilization` of the
    time; an error on the idle bus spoils nothing)."""
    return ber * bitrate * min(1.0, utilization)


def exceed_probability(rate_per_s: float, burst: int | None, interval_ns: int, hours: float = 1.0) -> float:
    """Probability (an upper bound) that errors at rate_per_s break the model within `hours`; burst None: the
    error-free assumption, broken by any error."""
    span_s = hours * 3600.0
    if rate_per_s <= 0:
        return 0.0
    if burst is None:
        return 1.0 - exp(-rate_per_s * span_s)
    per_interval = rate_per_s * interval_ns / 1e9  # lambda * T_err
    if per_interval >= 1:
        return 1.0
    starts = rate_per_s * span_s  # expected errors in the span: each may start an excess
    total = 0.0
    for m in range(1, MAX_TERMS):
        term = poisson_tail(per_interval * m, m + burst)
        total += term
        if starts * total >= 1:
            return 1.0  # the bound says nothing more
        if term <= total * 1e-15:
            return starts * total
    return 1.0  # not converged within MAX_TERMS (lambda * T_err a hair under 1): no bound below 1


def poisson_tail(mean: float, k: int) -> float:
    """P(X >= k) for X ~ Poisson(mean), summed upward from k in log space (k well above the mean here)."""
    if k <= 0:
        return 1.0
    if mean <= 0:
        return 0.0
    log_term = -mean + k * log(mean) - lgamma(k + 1)
    term = exp(log_term)
    total = 0.0
    i = k
    while term > 0:
        total += term
        i += 1
        term *= mean / i
        if term <= total * 1e-17:
            break
    return min(1.0, total)


@dataclass(frozen=True)
class Breach:
    """Where a sequence of error instants first leaves the model: error `last` comes less than (count - n) * T_err
    after error `first` (count = last - first errors after it), or None when it never does."""

    first_ns: int
    last_ns: int
    count: int  # errors in [first, last], both included


def first_breach(error_ns: Sequence[int], burst: int | None, interval_ns: int) -> Breach | None:
    """The first pair of errors that breaks `n + ceil(t / T_err)` errors per window (burst None: no error allowed).
    With g_j = t_j - j T_err, errors i < j break it iff t_j - t_i < (j - i - n) T_err, i.e. g_j < g_i - n T_err:
    a running maximum of g finds the first j in one pass."""
    if not error_ns:
        return None
    if burst is None:
        return Breach(error_ns[0], error_ns[0], 1)
    best_g, best_i = error_ns[0], 0
    for j in range(1, len(error_ns)):
        g = error_ns[j] - j * interval_ns
        if g < best_g - burst * interval_ns:
            return Breach(error_ns[best_i], error_ns[j], j - best_i + 1)
        if g >= best_g:  # on a tie the later error: the shorter window
            best_g, best_i = g, j
    return None
