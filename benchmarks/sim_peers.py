"""Peer baselines for the simulator benchmark: a plain simpy frame-level CAN model and python-can's virtual bus.

DESIGN.md's target for `netcfg simulate` is stated against these two peers, so both are measured here, on this
machine, on the same frames:
  1. `simpy_can`: the model a typical engineer writes with simpy: one process per periodic message, the bus a
     priority resource (priority = identifier), held for the frame time; max response time per identifier;
  2. `python_can_virtual`: frames sent and received between two python-can `virtual` bus instances (no timing
     model at all: the cost of moving a frame object through python-can's software bus).
The message set (`fully_loaded_set`) loads a 1 Mbit/s bus to 90 % with worst-case stuffing. The simulator
benchmark also compares netcfg's simulated maximum response times with `simpy_can`'s on the same set
(`response_maxima_match`), so the simpy model follows the same arbitration rule as netcfg.sim (see simpy_can).

    python benchmarks/sim_peers.py
"""

from __future__ import annotations

import gc
import random
import time
from collections.abc import Callable, Generator, Sequence
from typing import Any, NamedTuple

import can
import simpy

from netcfg.timing.frames import bits_to_ns, can_frame_bits

PERIODS_MS = (1, 2, 5, 10, 20, 50, 100)
MS = 1_000_000  # ns
RUNS = 3
SIM_SECONDS = 10
VIRTUAL_FRAMES = 200_000


class PeerFrame(NamedTuple):
    can_id: int
    period_ns: int
    offset_ns: int
    duration_ns: int  # worst-case transmission time, inter-frame space included


class PeerResult(NamedTuple):
    frames: int
    wall_s: float
    frames_per_s: float
    realtime_x: float | None  # simulated time / wall time; None when nothing is simulated in time
    max_response_ns: dict[int, int]  # per identifier; empty when there is no timing model


def simpy_can(frames: Sequence[PeerFrame], duration_ns: int, exact_ties: bool = True) -> PeerResult:
    """Simulate `frames` on one CAN bus for duration_ns of bus time; counts the frames completed before then.

    Each message is one process: it releases instance k at offset + k * period, queues it on the bus and
    records completion - release. The bus is a simpy PreemptiveResource used as a PriorityResource (lower
    identifier = higher priority, FIFO among instances of one identifier), so when a frame ends the lowest
    pending identifier gets the bus: CAN arbitration, non-preemptive once a frame is on the wire.

    Ties: a frame released at the very instant the bus becomes idle (or two frames released together on an
    idle bus) must take part in that arbitration. simpy grants a free resource to the first request made, and
    which of several events at one instant runs first is only their scheduling order, so the grant alone could
    let a higher identifier win. A request therefore asks to preempt exactly when the bus user's transmission
    started at this same instant (its arbitration is still open); simpy then takes the bus from it if the new
    identifier is lower and the loser queues again, keeping its release time. Frames already on the wire
    (started earlier) are never preempted. The outcome depends on no event order within an instant.
    exact_ties=False drops this (a plain PriorityResource, first request on an idle bus wins), to show its cost.
    """
    env = simpy.Environment()
    bus = simpy.PreemptiveResource(env, capacity=1) if exact_ties else simpy.PriorityResource(env, capacity=1)
    worst: dict[int, int] = {}
    count = 0

    def send(frame: PeerFrame) -> Generator[simpy.Event, Any, None]:
        while True:
            users = bus.users
            contest = exact_ties and bool(users) and users[0].usage_since == env.now
            with bus.request(priority=frame.can_id, preempt=contest) as req:
                try:
                    yield req
                    yield env.timeout(frame.duration_ns)
                    return
                except simpy.Interrupt:
                    pass  # lost the arbitration of this instant: queue again

    def message(frame: PeerFrame) -> Generator[simpy.Event, Any, None]:
        nonlocal count
        release = frame.offset_ns
        while True:
            if release > env.now:
                yield env.timeout(release - env.now)
            yield from send(frame)
            response = int(env.now) - release
            if response > worst.get(frame.can_id, -1):
                worst[frame.can_id] = response
            count += 1
            release += frame.period_ns  # an instance still queued at its successor's release delays it

    start = time.perf_counter()
    for f in frames:
        env.process(message(f))
    env.run(until=duration_ns)
    wall = time.perf_counter() - start
    return PeerResult(count, wall, count / wall, duration_ns / 1e9 / wall, worst)


def python_can_virtual(n_frames: int, batched: bool = False) -> PeerResult:
    """Send n_frames from one python-can virtual bus to another on the same channel and receive them all.

    batched=False: send then receive each frame; batched=True: send all, then receive all."""
    rng = random.Random(n_frames)
    msgs = [can.Message(arbitration_id=rng.randrange(0x800), is_extended_id=False, data=bytes(rng.randrange(9)))
            for _ in range(min(n_frames, 4096))]  # fmt: skip
    tx = can.Bus(interface="virtual", channel="netcfg-sim-peers")
    rx = can.Bus(interface="virtual", channel="netcfg-sim-peers")
    try:
        got = 0
        start = time.perf_counter()
        if batched:
            for i in range(n_frames):
                tx.send(msgs[i % len(msgs)])
            for _ in range(n_frames):
                got += rx.recv(timeout=1.0) is not None
        else:
            for i in range(n_frames):
                tx.send(msgs[i % len(msgs)])
                got += rx.recv(timeout=1.0) is not None
        wall = time.perf_counter() - start
    finally:
        tx.shutdown()
        rx.shutdown()
    if got != n_frames:
        raise RuntimeError(f"python-can virtual bus delivered {got} of {n_frames} frames")
    return PeerResult(n_frames, wall, n_frames / wall, None, {})


def fully_loaded_set(bitrate: int = 1_000_000, load: float = 0.9, seed: int = 0) -> list[PeerFrame]:
    """A random periodic set loading a plain 11-bit CAN bus to just under `load` (worst-case stuffing).

    Messages (period from PERIODS_MS, 0-8 data bytes) are drawn until none more fits under `load`.
    Identifiers are unique and deadline-monotonic (shorter period = lower id), as a CAN designer assigns
    them, so the set is schedulable (netcfg's CAN RTA gives every message a worst-case response time within its
    period for seeds 0-49) and no instance is still queued when its successor is released.
    Offsets are whole milliseconds below the period, as on ECUs with a 1 ms tick: many releases coincide,
    which exercises the arbitration ties. Deterministic for a given seed."""
    rng = random.Random(seed)
    drawn: list[tuple[int, int]] = []  # (period_ns, duration_ns)
    used, misses = 0.0, 0
    while misses < 1000 and len(drawn) < 0x800:
        period = rng.choice(PERIODS_MS) * MS
        duration = bits_to_ns(can_frame_bits(rng.randint(0, 8), False, "worst"), bitrate)
        if used + duration / period > load:
            misses += 1
            continue
        drawn.append((period, duration))
        used += duration / period
    ids = sorted(rng.sample(range(0x800), len(drawn)))
    order = sorted(drawn, key=lambda pd: (pd[0], rng.random()))
    return [PeerFrame(i, p, rng.randrange(p // MS) * MS, d) for i, (p, d) in zip(ids, order)]


def utilisation(frames: Sequence[PeerFrame]) -> float:
    return sum(f.duration_ns / f.period_ns for f in frames)


def response_maxima_match(a: dict[int, int], b: dict[int, int]) -> list[int]:
    """Identifiers whose maximum response times differ, or that only one side has (sorted)."""
    return sorted(i for i in a.keys() | b.keys() if a.get(i) != b.get(i))


def median_run(fn: Callable[[], PeerResult], runs: int = RUNS) -> PeerResult:
    """The run with the median wall time of `runs` runs (a shared machine: the median resists outliers)."""
    results = []
    for _ in range(runs):
        gc.collect()
        results.append(fn())
    return sorted(results, key=lambda r: r.wall_s)[len(results) // 2]


def main() -> None:
    frames = fully_loaded_set()
    duration = SIM_SECONDS * 1_000_000_000
    print(
        f"message set: {len(frames)} messages, 11-bit ids, 1 Mbit/s, worst-case load {utilisation(frames):.4f}, "
        f"{sum(duration // f.period_ns for f in frames):,} releases in {SIM_SECONDS} s; median of {RUNS} runs"
    )
    sim = median_run(lambda: simpy_can(frames, duration))
    loose = median_run(lambda: simpy_can(frames, duration, exact_ties=False))
    wrong = len(response_maxima_match(sim.max_response_ns, loose.max_response_ns))
    one = median_run(lambda: python_can_virtual(VIRTUAL_FRAMES))
    batch = median_run(lambda: python_can_virtual(VIRTUAL_FRAMES, batched=True))
    rows = [
        ("simpy frame-level model", f"{sim.frames:,}", f"{sim.wall_s:.3f}", f"{sim.frames_per_s:,.0f}",
         f"{sim.realtime_x:.1f}x"),
        ("simpy, arbitration ties ignored", f"{loose.frames:,}", f"{loose.wall_s:.3f}", f"{loose.frames_per_s:,.0f}",
         f"{loose.realtime_x:.1f}x"),
        ("python-can virtual, send+recv each", f"{one.frames:,}", f"{one.wall_s:.3f}", f"{one.frames_per_s:,.0f}", "-"),
        ("python-can virtual, sends then recvs", f"{batch.frames:,}", f"{batch.wall_s:.3f}",
         f"{batch.frames_per_s:,.0f}", "-"),
    ]  # fmt: skip
    headers = ("peer", "frames", "wall s", "frames/s", "x real time")
    widths = [max(len(r[i]) for r in [headers, *rows]) for i in range(len(headers))]
    for r in [headers, tuple("-" * w for w in widths), *rows]:
        print("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))))
    slowest = max(sim.max_response_ns, key=lambda i: sim.max_response_ns[i])
    print(f"simpy: largest max response {sim.max_response_ns[slowest] / 1e3:,.0f} us (id 0x{slowest:03X}); "
          f"ignoring ties changes the max response of {wrong} of {len(frames)} messages")  # fmt: skip


if __name__ == "__main__":
    main()
