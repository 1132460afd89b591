"""Worst-case response times on a CAN bus where commands and the replies they cause form transactions.

A reply that a node sends in answer to a command (an actuator's feedback frame) is released by that command's
frame, so it is not independent of it: taken apart (the holistic analysis, Tindell and Clark 1994), the reply gets
its command's whole response range plus the reply delay as release jitter, and the same commands are then counted
again as interference that may come at any phase. Here a command and its reply are one transaction on the
commander's clock, with dynamic offsets: Palencia and Gonzalez Harbour (1998, "Schedulability analysis for tasks
with static and dynamic offsets", RTSS, the WCDO approach) give a job released by another job an offset equal to
the earliest instant it can be released and a jitter up to the latest, iterated to a fixed point:

    offset  phi_r = phi_c + C_best(c) + lead_r            (its command's earliest end, then the shortest way to
                                                           the reply's queueing: rx delay, BCET, tx delay)
    jitter  J_r   = R_c + (the reply task's longest way) - C_best(c) - lead_r

R_c being the command's worst-case response from its own nominal release. The transactions are then analysed by
can_offsets (the sufficient test of Yomsi et al. 2012 over Tindell's transactions), which takes every job's own
jitter around its offset.

The anchor of a transaction is the commander's: the commands a task sends as it ends are queued together, at that
task's end (their nominal release is the same instant, each with its own jitter after it); commands at a fixed
offset of their sender's clock keep their offsets (`anchors` says which commands share a clock and at what offset).

Soundness: the iteration starts from the offset-free bounds (`base`, sound) and each round's offsets and jitters
come from bounds proved in the round before, so every round's bounds are sound; a message keeps the smallest it
was given. The reply's holistic jitter J_base (from the same analysis as `base`) is J_r at R_c = base R_c, so the
reply task's longest way needs no separate figure: J_r = J_base - (base R_c - R_c).

Reference: the bound of a reply is its nominal release (phi_r from the anchor), as the holistic bound's; it is
reported from its command's earliest end (phi_c + C_best(c)), lead_r later, so that it also bounds a reply's time
after its command's frame as a bus log shows it (netcfg.verify measures it so).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

from netcfg.timing import can_offsets
from netcfg.timing.can_errors import ErrorModel
from netcfg.timing.can_rta import CanFrame, Response

MAX_ROUNDS = 10  # rounds of the dynamic-offset iteration; each round's bounds are sound, so stopping early is too


@dataclass(frozen=True)
class Answer:
    """A reply on the bus and what releases it."""

    command: str  # the message whose frame releases it
    lead_ns: int  # shortest time from the command's frame end to the reply's queueing (rx delay + BCET + tx delay)
    best_ns: int  # the command's best-case frame time (no stuff bits)


def analyse(
    frames: Sequence[CanFrame],
    tau_ns: int,
    offsets: Mapping[str, tuple[str, int]],
    anchors: Mapping[str, tuple[str, int]],
    answers: Mapping[str, Answer],
    base: Mapping[str, Response],
    tolerance_ppm: int = 0,
    errors: ErrorModel | None = None,
) -> dict[str, Response]:
    """Every frame's response with its commands and replies held as transactions; never above `base` (the bounds
    without them, sound). `offsets`: the static release offsets (message -> (clock, offset)); `anchors`: each
    command -> (the clock it is released on, its offset there); `answers`: each reply -> what releases it."""
    by_name = {f.name: f for f in frames}
    pairs = {
        r: a
        for r, a in answers.items()
        if r in by_name and a.command in by_name and a.command in anchors and by_name[r].t_ns
        and by_name[r].t_ns == by_name[a.command].t_ns
    }
    out = dict(base)
    if not pairs:
        return out
    placed = dict(offsets)
    for reply, answer in pairs.items():
        clock, at = anchors[answer.command]
        placed[answer.command] = (clock, at)
        placed[reply] = (clock, at + answer.best_ns + answer.lead_ns)
    for _ in range(MAX_ROUNDS):
        shaped = []
        for f in frames:
            if (a := pairs.get(f.name)) is None:
                shaped.append(f)
                continue
            now, was = out[a.command].wcrt_ns, base[a.command].wcrt_ns
            if now is None or was is None or base[f.name].wcrt_ns is None:
                shaped.append(f)  # no bound for the command: the reply keeps the holistic jitter (it has none)
                placed.pop(f.name, None)
                continue
            shaped.append(replace(f, j_ns=max(0, f.j_ns - (was - now))))
        got = can_offsets.analyse(shaped, tau_ns, placed, tolerance_ppm, errors, latest=True)
        changed = False
        for f in frames:
            if (bound := got[f.name].wcrt_ns) is None:
                continue
            if (paired := pairs.get(f.name)) is not None and f.name in placed:
                bound += paired.lead_ns  # from its command's earliest end, not its own nominal release
            held = out[f.name].wcrt_ns
            if held is None or bound < held:
                out[f.name] = replace(out[f.name], wcrt_ns=bound)
                changed = True
        if not changed:
            break
    return out
