"""Raw frames over a CAN link, classical or FD: the spec's messages as they are, arbitrating by identifier, released
at their offsets, through priority or FIFO transmit queues. Everything is the link's: the resolution rules, the
arbitration analysis and what it assumes. An actuator's reply answers its command on the same bus: the two are one
transaction (answers)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg.links.can import CLASSICAL_CAN
from netcfg.links.canfd import CAN_FD
from netcfg.protocols.base import Protocol, Unsaid

if TYPE_CHECKING:
    from netcfg import model


class Raw(Protocol):
    carries_actuators = True  # raw frames are what an actuator's own protocol sends

    def answers(self, m: model.Model, bus: model.Bus) -> dict[str, tuple[str, int]]:
        """Each actuator reply on the bus -> (its command, the shortest way from the command's frame end to the
        reply's queueing: the actuator's rx delay, its reply task's BCET (the reply delay's lower end), its tx
        delay), when the reply task the command starts sends it (netcfg.resolve.actuators)."""
        on_bus = {msg.name for msg in bus.messages}
        out: dict[str, tuple[str, int]] = {}
        for node in m.nodes.values():
            for record in (node.actuator or {}).get("commands", ()):
                reply, command = record.get("reply_message"), record.get("message")
                senders = m.sent_by.get(reply, ()) if reply else ()
                if reply not in on_bus or command not in on_bus or len(senders) != 1:
                    continue
                task = m.task(senders[0])
                if task.on_message != command or task.node != node.name:
                    continue
                out[reply] = (command, node.rx_delay_ns + task.bcet_ns + node.tx_delay_ns)
        return out

    def dbc_unsaid(self, m: model.Model, bus: model.Bus) -> tuple[Unsaid, ...]:
        replies = sorted(self.answers(m, bus))
        if not replies:
            return ()
        return (
            Unsaid(
                f"replies held with their commands as transactions ({', '.join(replies)}): a DBC has no tasks and no "
                "replies, so check of the DBC bounds each reply as released on its own, a looser bound (still sound)",
                False,
            ),
        )


CAN = Raw("can", CLASSICAL_CAN)
# raw frames go over either CAN link: `protocol: can` with `link: can-fd` is the can-fd protocol
CAN_FD_RAW = Raw("can-fd", CAN_FD, twin_of=CAN)
