"""One EtherCAT cycle on the wire: the process image's frames, each slave's forwarding delay and the cables, and
when the last frame has passed each slave. The segment's analysis and its PDO messages' delivery both read it."""

from __future__ import annotations

from dataclasses import dataclass

from netcfg import model
from netcfg.links import ethercat as link
from netcfg.protocols.ethercat.segment import Segment


@dataclass(frozen=True)
class CycleTiming:
    frames: tuple[int, ...]  # data bytes of each frame's datagram
    frame_bytes: tuple[int, ...]  # each frame on the wire
    wire_ns: int  # all frames back to back: the bus's busy time
    forwarding_ns: int  # the slaves' forwarding delays
    propagation_ns: int  # the cables, out and back
    jitter_ns: int
    passed_ns: tuple[int, ...]  # per slave: the last frame's end has passed it, from the cycle's start

    @property
    def latency_ns(self) -> int:
        """From the cycle's start to the last frame back at the master."""
        return self.jitter_ns + self.wire_ns + self.forwarding_ns + self.propagation_ns


def cycle_timing(
    image_bytes: int, bitrate: int, forwarding_ns: list[int], cables_m: list[float], jitter_ns: int = 0
) -> CycleTiming:
    frames = tuple(link.split_image(image_bytes))
    sizes = tuple(link.frame_bytes([d]) for d in frames)
    wire = link.wire_ns(sum(sizes), bitrate)
    passed, fwd, prop = [], 0.0, 0.0
    for d, cable in zip(forwarding_ns, cables_m):
        fwd += d
        prop += link.propagation_ns(cable)
        passed.append(round(jitter_ns + wire + fwd + prop))
    return CycleTiming(frames, sizes, wire, round(fwd), round(2 * prop), jitter_ns, tuple(passed))


def segment_timing(bus: model.Bus, seg: Segment) -> CycleTiming:
    return cycle_timing(
        seg.out_bytes + seg.in_bytes,
        bus.bitrate,
        [s.forwarding_ns for s in seg.slaves],
        [s.cable_m for s in seg.slaves],
        seg.master_jitter_ns,
    )
