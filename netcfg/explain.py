"""The derivation of one CAN message's worst-case response time, as `netcfg check SPEC --explain MESSAGE` prints it.

It restates the terms of the revised CAN analysis (Davis, Burns, Bril and Lukkien 2007, eqs. 5, 10-14) for that
message at its worst instance: frame time with stuff bits, blocking frame, every higher-priority message and how
many times it hits in the queuing delay w, the busy period, jitter and (when the bus has one) the error term; then
the offset-aware bound if offsets lowered it, and, for a message that misses, the one change that makes it meet:
a free identifier high enough, or else a slower rate of one named interferer.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

from netcfg import links, model, protocols
from netcfg.analyze import analysis_jitter
from netcfg.bus_analysis import error_model
from netcfg.links.arbitration import bus_responses, fifo_inputs, fifo_senders, rta_frames, transaction_responses
from netcfg.protocols import release_offsets
from netcfg.spec.units import format_ns
from netcfg.timing import can_fifo, can_offsets, can_rta, clocks, load
from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.frames import bits_to_ns
from netcfg.tuning import round_step


class NotExplained(Exception):
    """The message is unknown or not on a CAN bus."""


def _us(ns: int | None) -> float | None:
    return None if ns is None else round(ns / 1000, 3)


def _message(m: model.Model, name: str) -> model.Message | None:
    """A message of the spec, or one the protocol adds (a CANopen SYNC, a heartbeat): check's table lists both."""
    msg = m.messages.get(name)
    if msg is None:
        msg = next((x for bus in m.buses.values() for x in bus.messages if x.name == name), None)
    return msg


def explain(m: model.Model, name: str) -> dict[str, Any]:
    msg = _message(m, name)
    if msg is None:
        known = [*m.messages, *m.flows, *(x.name for bus in m.buses.values() for x in bus.messages if x.implicit)]
        close = difflib.get_close_matches(name, known, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise NotExplained(f"no message or flow '{name}' in system '{m.system}'{hint}")
    bus = m.buses[msg.bus]
    if not links.of(bus).arbitrates:
        raise NotExplained(f"'{name}' is on Ethernet bus '{bus.name}'; --explain derives CAN response times")
    timings, _, _ = load.can_bus_load(bus)
    tau = bits_to_ns(1, bus.bitrate)
    given = rta_frames(bus.messages, timings, analysis_jitter(m))  # the release jitter check uses
    ppm = bus.clock_tolerance_ppm
    errors = error_model(bus)
    fifo = bus_responses(m, bus, given, tau, release_offsets(m, bus))
    # FIFO-queued frames reach arbitration up to their queue's bound late: other frames see that as jitter
    frames = [replace(f, j_ns=fifo.effective_jitter_ns.get(f.name, f.j_ns)) for f in given]
    plain = can_rta.analyse(frames, tau, ppm, errors)
    with_offsets = can_offsets.analyse(frames, tau, release_offsets(m, bus), ppm, errors)
    # FIFO members, and frames an unbounded FIFO above them leaves unbounded, take the FIFO analysis' verdict
    plain.update(
        {n: r for n, r in fifo.responses.items() if n in fifo.effective_jitter_ns or r.limit == "fifo"}
    )
    with_offsets = {**with_offsets, **fifo.responses}
    me = next(f for f in given if f.name == name)
    r = plain[name]
    t = timings[name]
    out: dict[str, Any] = {
        "message": name,
        "bus": bus.name,
        "protocol": bus.protocol,
        "bitrate": bus.bitrate,
        "tau_us": _us(tau),
        "id": msg.id,
        "frame": {
            "size": msg.size,
            "bits_nominal": t.bits_nominal,
            "stuff_bits_worst": t.bits_worst - t.bits_nominal,
            "bits_worst": t.bits_worst,
            "c_us": _us(me.c_ns),
        },
        "period_us": _us(me.t_ns),
        "jitter_us": _us(me.j_ns),
        "deadline_us": _us(me.d_ns),
        "blocking": _blocking(frames, me),
        "error_term_us": None,  # None: the bus states no error model, no error frames are assumed
        "error_term": None,
        "busy_period_us": _us(r.busy_period_ns),
        "instances": r.instances,
        "worst_instance": r.worst_instance,
        "wcrt_us": _us(r.wcrt_ns),
        "unbounded": r.limit,
        "wcrt_with_offsets_us": _us(with_offsets[name].wcrt_ns),
        "wcrt_as_transaction_us": None,  # a reply held with its command (netcfg.timing.can_transactions)
        "interferers": [],
        "w_us": None,
    }
    bound = with_offsets[name].wcrt_ns
    proto = protocols.of(bus)
    held = transaction_responses(m, bus, proto, given, timings, tau, release_offsets(m, bus), fifo.responses)
    if held is not fifo.responses and (tx := held[name].wcrt_ns) is not None and (bound is None or tx < bound):
        out["wcrt_as_transaction_us"], bound = _us(tx), tx
    queue = next((q for q in fifo.queues.values() if name in q.members), None)
    if queue is not None:
        out.update(_fifo_terms(m, frames, queue, name, tau, ppm, errors))
    elif r.wcrt_ns is not None:
        q = r.worst_instance
        t_me = me.t_ns or can_rta.ONE_SHOT
        w = r.wcrt_ns - me.j_ns + clocks.shortest_real(q * t_me, ppm) - me.c_ns
        out["w_us"] = _us(w)
        if errors is not None:
            largest = max(f.c_ns for f in frames if f.priority_key <= me.priority_key)
            out["error_term_us"] = _us(r.error_ns)
            out["error_term"] = _error_term(errors, w + me.c_ns, largest)
        out["interferers"] = _interferers([f for f in frames if f.priority_key < me.priority_key], w, tau, ppm)
    promised = not (msg.may_be_lost and with_offsets[name].limit == "dropped")  # as check's verdict: none
    out["meets"] = None if me.d_ns is None or not promised else bound is not None and bound <= me.d_ns
    out["slack_us"] = None if me.d_ns is None or bound is None else _us(me.d_ns - bound)
    if out["meets"] in (None, True):
        out["fix"] = None
    elif queue is not None:
        out["fix"] = _priority_queue(_Trials(m, bus, given, me, tau), queue)
    else:
        out["fix"] = one_change(_Trials(m, bus, given, me, tau))
    return out


def _fifo_terms(
    m: model.Model,
    frames: list[can_rta.CanFrame],
    q: can_fifo.FifoQueue,
    name: str,
    tau: int,
    ppm: int,
    errors: ErrorModel | None,
) -> dict[str, Any]:
    """The FIFO bound's terms (Davis, Kollmann, Pollex, Slomka 2011): the frames that can be ahead in the queue,
    the blocking and the other nodes' frames above the queue's lowest-priority message, with their hits."""
    by_name = {f.name: f for f in frames}
    b = q.bounds.get(name)  # the member's own bound; the queue's largest when it has none
    if b is None:
        b = can_fifo.FifoBound(
            q.members, q.lowest, q.blocking_ns, q.queued_ns, q.c_min_ns, q.interference_ns, q.queue_ns, q.limit,
            q.error_ns,
        )
    lowest = by_name[b.lowest]
    out: dict[str, Any] = {
        "queue": {
            "node": q.node,
            "depth": m.nodes[q.node].tx_queue.depth,
            "on_full": m.nodes[q.node].tx_queue.on_full,
            "lowest": b.lowest,
            "frames": [{"name": n, "id": by_name[n].id, "c_us": _us(by_name[n].c_ns)} for n in b.together],
            "members": len(q.members),
            "queued_us": _us(b.queued_ns),
            "c_min_us": _us(b.c_min_ns),
            "queue_us": _us(b.queue_ns),
            "unbounded": q.limit,
        },
        "blocking": _blocking([f for f in frames if f.name not in q.members], lowest),
        "busy_period_us": None,
        "instances": 1,
        "worst_instance": 0,
        "interferers": [],
    }
    if q.queue_ns is None or b.queue_ns is None:
        return out
    w = b.queue_ns - b.c_min_ns
    out["w_us"] = _us(w)
    if errors is not None:  # E(w + C_MIN), the largest frame of the bus resent (can_fifo)
        out["error_term_us"] = _us(b.error_ns)
        out["error_term"] = _error_term(errors, b.queue_ns, max(f.c_ns for f in frames))
    above = [f for f in frames if f.priority_key < lowest.priority_key and f.name not in q.members]
    out["interferers"] = _interferers(above, w, tau, ppm)
    return out


def _error_term(errors: ErrorModel, window_ns: int, largest_ns: int) -> dict[str, Any]:
    """E(window): the errors the model allows in the window, each an error frame and the largest frame resent."""
    return {
        "burst": errors.burst,
        "interval_us": _us(errors.interval_ns),
        "window_us": _us(window_ns),
        "errors": errors.errors_in(window_ns),
        "error_frame_us": _us(errors.error_frame_ns),
        "largest_frame_us": _us(largest_ns),
    }


def _interferers(above: list[can_rta.CanFrame], w: int, tau: int, ppm: int) -> list[dict[str, Any]]:
    """Each higher-priority frame's releases in the queuing window w + tau (on its sender's clock, as can_rta
    counts them), in priority order."""
    out = []
    for f in sorted(above, key=lambda f: f.priority_key):
        hits = -(-clocks.longest_local(w + f.j_ns + tau, ppm) // (f.t_ns or can_rta.ONE_SHOT))
        out.append(
            {
                "name": f.name,
                "id": f.id,
                "c_us": _us(f.c_ns),
                "period_us": _us(f.t_ns),
                "jitter_us": _us(f.j_ns),
                "hits": hits,
                "us": _us(hits * f.c_ns),
            }
        )
    return out


@dataclass(frozen=True)
class _Trials:
    """A message that misses its deadline, on its bus as check analysed it: each change explain tries is a variant
    of the bus (other frames, offsets or queues), bounded by the same FIFO and offset-aware analyses."""

    m: model.Model
    bus: model.Bus
    frames: list[can_rta.CanFrame]
    me: can_rta.CanFrame
    tau: int

    @cached_property
    def fifo_of(self) -> dict[str, str]:
        return fifo_senders(self.m, self.bus)

    @cached_property
    def release(self) -> dict[str, tuple[str, int]]:
        return release_offsets(self.m, self.bus)

    @cached_property
    def errors(self) -> ErrorModel | None:
        return error_model(self.bus)

    def offsets(self, fifo_of: dict[str, str]) -> dict[str, tuple[str, int]]:
        """The release offsets of the frames no FIFO of `fifo_of` queues (a FIFO member's are its queue's inputs)."""
        return {n: o for n, o in self.release.items() if n not in fifo_of}

    def fifo_inputs(self) -> dict[str, int]:
        return fifo_inputs(self.m, self.bus, self.release)[0]

    def bound(
        self,
        frames: list[can_rta.CanFrame],
        offsets: dict[str, tuple[str, int]],
        fifo_of: dict[str, str],
        fifo_offsets: dict[str, int] | None = None,
    ) -> int | None:
        """The message's bound in this variant of the bus, or None when it still misses its deadline."""
        ppm, errors, tau = self.bus.clock_tolerance_ppm, self.errors, self.tau
        res = can_fifo.analyse(
            frames, tau, fifo_of, lambda fs: can_offsets.analyse(fs, tau, offsets, ppm, errors), ppm, errors,
            fifo_offsets,
        ).responses
        f = next(f for f in frames if f.name == self.me.name)
        r = res[f.name].wcrt_ns
        return r if r is not None and f.d_ns is not None and r <= f.d_ns else None


def _priority_queue(t: _Trials, q: can_fifo.FifoQueue) -> dict[str, Any] | None:
    """A FIFO member's bound does not depend on its identifier; the change that matters is the queue itself."""
    me = t.me
    fifo_of = {n: node for n, node in t.fifo_of.items() if node != q.node}
    kept = {n: o for n, o in t.fifo_inputs().items() if n in fifo_of}
    r = t.bound(t.frames, t.offsets(fifo_of), fifo_of, kept)
    if r is None or me.d_ns is None:
        return None
    return {
        "kind": "queue",
        "wcrt_us": _us(r),
        "text": f"queue the frames of '{q.node}' by priority (tx_queue: priority, a controller with a mailbox per "
        f"message): the bound of '{me.name}' becomes {r / 1000:g} us <= {me.d_ns / 1000:g} us",
    }


def _blocking(frames: list[can_rta.CanFrame], me: can_rta.CanFrame) -> dict[str, Any]:
    lower = [f for f in frames if f.priority_key > me.priority_key]
    if not lower:
        return {"by": None, "us": 0.0}
    worst = max(lower, key=lambda f: (f.c_ns, -f.priority_key))
    return {"by": worst.name, "us": _us(worst.c_ns)}


def one_change(t: _Trials) -> dict[str, Any] | None:
    """A free identifier for the message that makes it meet its deadline (the largest such, the least change in
    priority), else an offset, else a longer period for the one interferer that needs the smallest slow-down."""
    frames, me = t.frames, t.me
    fifo_of, offsets, fifo_offsets = t.fifo_of, t.offsets(t.fifo_of), t.fifo_inputs()
    taken = {(f.extended, f.id) for f in frames}
    others = [f for f in frames if f.name != me.name]
    for ident in range(me.id - 1, -1, -1):
        if (me.extended, ident) in taken:
            continue
        trial = [*others, replace(me, id=ident)]
        r = t.bound(trial, offsets, fifo_of, fifo_offsets)
        if r is not None:
            above = [f for f in others if f.priority_key > trial[-1].priority_key and f.priority_key < me.priority_key]
            passed = min(above, key=lambda f: f.priority_key).name if above else None
            return {
                "kind": "identifier",
                "id": ident,
                "wcrt_us": _us(r),
                "text": f"give '{me.name}' identifier 0x{ident:03X} (free"
                + (f"; above '{passed}'" if passed else "")
                + f"): its bound becomes {r / 1000:g} us <= {(me.d_ns or 0) / 1000:g} us",
            }
        if ident < me.id - 4096:  # far enough: the rest of the range only adds priority it does not need
            break
    offset = _offset_change(t, offsets)
    if offset is not None:
        return offset
    best: dict[str, Any] | None = None
    for f in sorted((f for f in frames if f.priority_key < me.priority_key and f.t_ns), key=lambda f: f.priority_key):
        assert f.t_ns is not None
        for factor in (2, 3, 4, 5, 10, 20, 50, 100):
            period = f.t_ns * factor
            trial = [replace(g, t_ns=period, d_ns=max(g.d_ns or 0, period)) if g is f else g for g in frames]
            r = t.bound(trial, offsets, fifo_of, fifo_offsets)
            if r is not None:
                if best is None or factor < best["factor"]:
                    best = {
                        "kind": "rate",
                        "interferer": f.name,
                        "factor": factor,
                        "period_us": _us(period),
                        "wcrt_us": _us(r),
                        "text": f"send '{f.name}' every {format_ns(period)} instead of {format_ns(f.t_ns)}: "
                        f"the bound of '{me.name}' becomes {r / 1000:g} us <= {(me.d_ns or 0) / 1000:g} us",
                    }
                break
    return best


def _offset_change(t: _Trials, offsets: dict[str, tuple[str, int]]) -> dict[str, Any] | None:
    """An offset for the message, against the offsets its sender's other messages already have."""
    me = t.me
    msg = t.m.messages[me.name]
    producer = msg.producer
    if not me.t_ns or not any(n != me.name and p == producer for n, (p, _) in offsets.items()):
        return None
    trial = {**offsets, me.name: (producer, 0)}
    if me.name not in t.release and (msg.kind != "periodic" or msg.period_ns != msg.interval_ns):
        return None
    step = round_step(me.t_ns // 64, 1000)
    best: tuple[int, int] | None = None  # (bound, offset): the offset that leaves the most slack
    for o in range(0, me.t_ns, step):
        trial[me.name] = (producer, o)
        r = t.bound(t.frames, trial, t.fifo_of)
        if r is not None and (best is None or r < best[0]):
            best = (r, o)
    if best is None:
        return None
    r, o = best
    return {
        "kind": "offset",
        "offset_us": _us(o),
        "wcrt_us": _us(r),
        "text": f"give '{me.name}' offset {format_ns(o)} on '{producer}', away from its sender's other messages: "
        f"its bound becomes {r / 1000:g} us <= {(me.d_ns or 0) / 1000:g} us",
    }


def text(doc: dict[str, Any]) -> str:
    f = doc["frame"]
    lines = [
        f"{doc['message']} (id 0x{doc['id']:03X}) on bus {doc['bus']} ({doc['protocol']}, {doc['bitrate']} bit/s, "
        f"bit time tau = {doc['tau_us']:g} us); Davis et al. 2007, eqs. 5, 10-14",
        f"  frame      {f['size']} bytes: {f['bits_nominal']} bits + up to {f['stuff_bits_worst']} stuff bits = "
        f"{f['bits_worst']} bits (3-bit intermission included): C = {f['c_us']:g} us",
        f"  release    period T = {_t(doc['period_us'])}, jitter J = {doc['jitter_us']:g} us, deadline D = "
        f"{_t(doc['deadline_us'])}",
        "  blocking   B = "
        + (
            f"{doc['blocking']['us']:g} us: '{doc['blocking']['by']}', the longest lower-priority frame"
            if doc["blocking"]["by"]
            else "0 us: no lower-priority frame"
        ),
    ]
    if doc.get("queue"):
        lines.extend(_fifo_text(doc))
    elif doc["wcrt_us"] is None and doc["unbounded"] == "fifo":
        lines.append(
            "  no bounded response: another node's FIFO transmit queue with a message above it has no bound, so its"
            " frames reach arbitration at no bounded time (the bus's tx_queues in check say which)"
        )
    elif doc["wcrt_us"] is None:
        lines.append("  no bounded response: the messages at and above its priority load the bus to 100 % or more")
    else:
        q = doc["worst_instance"]
        lines.append(
            f"  busy period t = {doc['busy_period_us']:g} us: {doc['instances']} instance(s); the worst is q = {q}"
        )
        e_part = " + E(w + C)" if doc["error_term"] else ""
        lines.append(
            f"  queuing    w = B + q*C + sum of ceil((w + J_k + tau) / T_k) * C_k{e_part} = {doc['w_us']:g} us, with:"
        )
        lines.extend(_interferer_lines(doc, "(no higher-priority message)"))
        lines.append(_error_line(doc, "w + C", "largest C at or above"))
        lines.append(
            f"  R = J + w - q*T + C = {doc['jitter_us']:g} + {doc['w_us']:g} - {q}*{_num(doc['period_us'])} + "
            f"{f['c_us']:g} = {doc['wcrt_us']:g} us"
        )
        if doc["wcrt_with_offsets_us"] is not None and doc["wcrt_with_offsets_us"] < doc["wcrt_us"]:
            lines.append(
                f"  with its sender's offsets (transaction analysis, netcfg.timing.can_offsets): "
                f"{doc['wcrt_with_offsets_us']:g} us"
            )
        if doc["wcrt_as_transaction_us"] is not None:
            lines.append(
                "  as one transaction with the command that releases it, or with the replies its own frames cause "
                "(dynamic offsets, Palencia and Gonzalez Harbour 1998; netcfg.timing.can_transactions): "
                f"{doc['wcrt_as_transaction_us']:g} us"
            )
    if doc["meets"] is True:
        lines.append(f"  meets its deadline with {doc['slack_us']:g} us to spare")
    elif doc["meets"] is False:
        lines.append("  MISSES its deadline" + (f" by {-doc['slack_us']:g} us" if doc["slack_us"] is not None else ""))
        lines.append(
            "  the one change: "
            + (
                doc["fix"]["text"]
                if doc["fix"]
                else "none found among a free identifier "
                "or a 2-100x slower interferer; lower the load or raise the bit rate"
            )
        )
    return "\n".join(lines)


def _error_line(doc: dict[str, Any], window: str, largest: str) -> str:
    """The error term's derivation E(window), or that the bus assumes no errors."""
    e = doc["error_term"]
    if e is None:
        return "  error term none: the bus states no error model (no error frames assumed)"
    return (
        f"  error term E({window}) = (n + ceil(({window}) / T_err)) * (error frame + {largest}) = "
        f"({e['burst']} + ceil({e['window_us']:g} / {e['interval_us']:g})) * ({e['error_frame_us']:g} + "
        f"{e['largest_frame_us']:g}) = {e['errors']} * {e['error_frame_us'] + e['largest_frame_us']:g} = "
        f"{doc['error_term_us']:g} us"
    )


def _interferer_lines(doc: dict[str, Any], none: str) -> list[str]:
    """The interferers' table of a derivation, or `none` when there are none."""
    if not doc["interferers"]:
        return [f"    {none}"]
    return [
        f"    {'message':20} {'id':>6} {'C/us':>8} {'T/us':>10} {'J/us':>8} {'hits':>5} {'us':>9}",
        *(
            f"    {x['name']:20} {_hex(x['id']):>6} {x['c_us']:>8g} {_num(x['period_us']):>10} "
            f"{x['jitter_us']:>8g} {x['hits']:>5} {x['us']:>9g}"
            for x in doc["interferers"]
        ),
    ]


def _fifo_text(doc: dict[str, Any]) -> list[str]:
    """The FIFO bound (Davis, Kollmann, Pollex, Slomka 2011) in the shape of the priority-queue derivation."""
    q = doc["queue"]
    lines = [
        f"  queue      '{q['node']}' sends through a FIFO (depth {q['depth']}, {q['on_full']} when full); any of the "
        f"frames below can be ahead, each once, and while one heads the queue it loses to every frame above "
        f"'{q['lowest']}', the queue's lowest-priority message (ECRTS 2011, section 4):",
        f"    {'in the queue':20} {'id':>6} {'C/us':>8}",
        *(f"    {x['name']:20} {_hex(x['id']):>6} {x['c_us']:>8g}" for x in q["frames"]),
        f"    sum of C = {q['queued_us']:g} us; C_MIN = {q['c_min_us']:g} us",
    ]
    if q["queue_us"] is None:
        why = {
            "fifo": "a member waits longer than its period, so two of its frames can be queued at once",
            "dropped": "its frame can find the queue full, and the queue drops it",
            "load": "the other nodes' frames above its lowest-priority message load the bus to 100 % or more",
        }.get(q["unbounded"] or "", "the bound needs too many steps of the analysis")
        return [*lines, f"  no bounded response: {why}"]
    lines.append(
        "  queuing    w = B + sum of C - C_MIN + sum of ceil((w + J_k + tau) / T_k) * C_k"
        + (" + E(w + C_MIN)" if doc["error_term"] else "")
        + f" = {doc['w_us']:g} us, with:"
    )
    lines.extend(_interferer_lines(doc, "(no other node's frame above the queue's lowest-priority message)"))
    lines.append(_error_line(doc, "w + C_MIN", "the bus's largest frame"))
    r = doc["jitter_us"] + doc["w_us"] + q["c_min_us"]
    if doc["unbounded"] == "dropped":
        return [
            *lines,
            f"  R = J + w + C_MIN = {r:g} us for the frames that get through, but a frame can find the queue full "
            "and be dropped: no bound",
        ]
    lines.append(
        f"  R = J + w + C_MIN = {doc['jitter_us']:g} + {doc['w_us']:g} + {q['c_min_us']:g} = {doc['wcrt_us']:g} us "
        + (
            "(the same queuing bound for every frame of the queue)"
            if len(q["frames"]) == q.get("members", len(q["frames"]))
            else "(only the frames listed can be queued with this one: its release offset keeps the others apart)"
        )
    )
    return lines


def _hex(ident: int) -> str:
    return f"0x{ident:03X}"


def _num(us: float | None) -> str:
    return "-" if us is None else f"{us:g}"


def _t(us: float | None, none: str = "none") -> str:
    return none if us is None else f"{us:g} us"
