"""A run's CAN frames as a trace: what `netcfg simulate --log` writes and holds against the analysis."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from netcfg.timing.frames import CANFD_PADDING, canfd_padded_size

if TYPE_CHECKING:
    from netcfg.sim.trace import TraceFrame


def trace_frames(sc: Any) -> list[TraceFrame]:
    """Every frame of every CAN bus, in time order, with error frames where a bit error hit."""
    from netcfg.sim.trace import TraceFrame

    out: list[TraceFrame] = []
    for name, bus in sc.can.items():
        rec = bus.record
        for m, end, data in zip(rec.msg, rec.end, rec.data):
            src = bus.sources[m]
            payload = data if data is not None else src.rest  # every field at rest, inside its range
            if src.fd:  # sent padded to its CAN FD length, as netcfg.runtime does
                payload += bytes([CANFD_PADDING]) * (canfd_padded_size(src.size) - src.size)
            out.append(TraceFrame(end, name, src.can_id, src.extended, payload, fd=src.fd, brs=src.brs))
        for t in bus.error_log:
            out.append(TraceFrame(t + bus.error_ns, name, 0, False, b"", True))
    out.sort(key=lambda f: (f.t_ns, f.channel))
    return out
