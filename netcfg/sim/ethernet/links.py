"""The pieces a switched Ethernet run is made of: a link (one direction of one cable, its transmitter and egress
queue), a receiving node's FIFO server, and the frame batches that flow between them.

Transmit queues are finite (each link's `queue_frames`, counting the frame being sent: the depth the runtime
configuration gives the sending NIC or switch port, by default netcfg.timing.ethernet.QUEUE_FRAMES as the analysis
assumes too): a frame that finds its queue full is dropped (tail drop) and counted per port and per message. Seed
001 (section 6.2.2.5) warns of exactly this: "the port's buffer may overflow and lead to unexpected delays or data
loss"; `netcfg check` refuses a spec whose queues can fill.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from netcfg.runtime import Task
    from netcfg.sim.flows import FlowTracker

CHUNK_NS = 5_000_000  # simulated time computed at once; frames fare the same for any value (random draws for
# jitter may come in another order)

_I64 = np.int64
_EMPTY = np.empty(0, dtype=_I64)
Batch = tuple[np.ndarray, np.ndarray, np.ndarray]  # (arrival at the stage, message index, release), aligned
# a frame at an event link, in the order frames leave a port: (arrival, release, message index, sequence number);
# frames that reach a port at the same instant leave in order of release, then of message index, whichever path
# computed them (take() keeps the same order), so the result does not depend on the order they became known in
Waiting = tuple[int, int, int, int]
Listen = tuple[list["FlowTracker"], list["Task"]]
Due = tuple[int, int, int, int, int]  # a waiting frame something observes: (serve it before this, *its Waiting)


@dataclass
class Link:
    """One direction of one cable with its transmitter and egress queue."""

    index: int
    src: str
    dst: str
    prop_ns: int
    latency_ns: int  # the switch at the far end (Tmux) before the next egress queue; 0 at a node
    crash_ns: int  # the sending node crashed: nothing starts from then on (NEVER for a switch)
    queue_frames: int  # frames its transmit queue holds, counting the one being sent
    busy_until: int = 0
    frames: int = 0
    busy_ns: int = 0
    max_queue: int = 0
    lost: int = 0
    offered: float = 0.0  # sum of rate x frame time over the messages crossing it: the analysis' utilisation
    # free-running links (numpy, a chunk at a time)
    pending: list[Batch] = field(default_factory=list)
    tail: np.ndarray = field(default_factory=lambda: _EMPTY)  # ends of the frames that may still be at the port
    # event links (frame by frame, see the module's docstring)
    event: bool = False
    takes_chained: bool = False  # a NIC that chained frames enter at the current instant
    waiting: list[Waiting] = field(default_factory=list)  # a heap, in arrival order (then in order of arrival known)
    due: list[Due] = field(default_factory=list)  # a heap of the waiting frames that something observes
    fresh: list[Due] = field(default_factory=list)  # the same, arrived since the link was last served
    route: list[Any] = field(default_factory=list)  # per message: (next links, delivery here), see _build_event_links
    ends: deque[int] = field(default_factory=deque)  # ends of the frames that may still be at the port
    feeders: list[tuple[Link, int]] = field(default_factory=list)  # (link, least delay from its end to here)
    served: int = -1  # every frame arriving here at or before this instant has been served


@dataclass
class Server:
    """A receiving node consuming frames one after another (FIFO, service drawn between BCET and WCET)."""

    node: str
    bcet: np.ndarray  # per message index
    wcet: np.ndarray
    batches: list[Batch] = field(default_factory=list)  # deliveries (end, message, release), served after the run
    ends: list[int] = field(default_factory=list)  # the same, delivered one by one
    msgs: list[int] = field(default_factory=list)
    rels: list[int] = field(default_factory=list)
    busy_ns: int = 0


def counts_by_index(idx: np.ndarray) -> list[tuple[int, int]]:
    """(index, how many times it occurs) for each index present, ascending: np.unique(idx, return_counts=True) for
    the message indices it is used on, without the numpy.ma import np.unique makes (5-10 ms of a simulate process)."""
    counts = np.bincount(idx)
    present = np.flatnonzero(counts)
    return list(zip(present.tolist(), counts[present].tolist()))


def take(pending: list[Batch], horizon: int) -> Batch | None:
    """The waiting frames that arrive before the horizon, in the order they leave the port (FIFO; on the same
    instant in order of release, then of message index, as Waiting); the others stay."""
    if not pending:
        return None
    if len(pending) == 1:
        t, msg, rel = pending[0]
    else:
        t = np.concatenate([b[0] for b in pending])
        msg = np.concatenate([b[1] for b in pending])
        rel = np.concatenate([b[2] for b in pending])
    if len(pending) > 1 or (t[1:] < t[:-1]).any():  # one batch is mostly in order already
        order = np.argsort(t, kind="stable")
        t, msg, rel = t[order], msg[order], rel[order]
    tied = np.flatnonzero(t[1:] == t[:-1])
    if len(tied):  # rare (two senders' frames on the same nanosecond): just those, by release, then message
        mark = np.zeros(len(t), dtype=bool)
        mark[tied] = mark[tied + 1] = True
        at = np.flatnonzero(mark)
        order = np.arange(len(t))
        order[at] = at[np.lexsort((msg[at], rel[at], t[at]))]
        t, msg, rel = t[order], msg[order], rel[order]
    k = int(np.searchsorted(t, horizon, side="left"))
    pending.clear()
    if k < len(t):
        pending.append((t[k:], msg[k:], rel[k:]))
    if k == 0:
        return None
    return t[:k], msg[:k], rel[:k]
