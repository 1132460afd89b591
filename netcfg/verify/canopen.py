"""CANopen service frames in a log (CiA 301, 7.3.3 predefined connection set: COB-ID = function code + node id):
NMT commands, heartbeats (and the NMT states they carry), EMCYs, SDO and the other services. They belong to no
configured message, yet they are not unknown when they come from the bus's nodes: this module tells them apart
(with numpy, for whole batches) and keeps what a report lists.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["ServiceLog"]

NMT_ID = 0x000
TIME_ID = 0x100
EMCY_BASE = 0x080
TSDO_BASE = 0x580
RSDO_BASE = 0x600
HEARTBEAT_BASE = 0x700
LSS_IDS = (0x7E4, 0x7E5)
FUNCTION_MASK = 0x780
NODE_MASK = 0x7F
NMT_STATES = {0x00: "boot-up", 0x04: "stopped", 0x05: "operational", 0x7F: "pre-operational"}
NMT_COMMANDS = {0x01: "start", 0x02: "stop", 0x80: "enter pre-operational", 0x81: "reset node", 0x82: "reset comm"}
MAX_LISTED = 1000  # NMT commands, state changes and EMCYs kept per bus; more are not listed


class ServiceLog:
    """One CANopen bus's service frames: `nodes` maps node ids to node names."""

    def __init__(self, nodes: dict[int, str]) -> None:
        self.nodes = nodes
        self._node_ids = np.array(sorted(nodes), np.int64)
        self.nmt: list[dict[str, Any]] = []
        self.emcy: list[dict[str, Any]] = []
        self.states: list[dict[str, Any]] = []
        self.heartbeats: dict[str, dict[str, Any]] = {}
        self.sdo = 0
        self.other = 0

    def take(self, t: NDArray[np.int64], can_id: NDArray[np.int64], data: NDArray[np.uint8]) -> NDArray[np.bool_]:
        """Standard-identifier frames of this bus that match no message -> which of them are services (noted)."""
        function, node = can_id & FUNCTION_MASK, can_id & NODE_MASK
        ours = np.isin(node, self._node_ids) & (node > 0)
        sdo = np.isin(function, (TSDO_BASE, RSDO_BASE)) & ours
        other = (can_id == TIME_ID) | np.isin(can_id, LSS_IDS)
        listed = (can_id == NMT_ID) | (np.isin(function, (EMCY_BASE, HEARTBEAT_BASE)) & ours)
        self.sdo += int(sdo.sum())
        self.other += int(other.sum())
        for k in np.flatnonzero(listed):  # few: heartbeats every 100 ms or so, NMT and EMCY rarely
            self._note(int(can_id[k]), int(t[k]), data[k])
        return np.asarray(sdo | other | listed)

    def note(self, can_id: int, t: int, data: NDArray[np.uint8]) -> None:
        """One NMT, heartbeat or EMCY frame, also when the configuration lists it as a message (its heartbeats)."""
        self._note(can_id, t, data)

    def _note(self, can_id: int, t: int, data: NDArray[np.uint8]) -> None:
        if can_id == NMT_ID:
            command, target = int(data[0]), int(data[1])
            who = "all nodes" if target == 0 else self.nodes.get(target, f"node {target}")
            _append(self.nmt, {"time_us": t, "command": NMT_COMMANDS.get(command, f"0x{command:02X}"), "node": who})
            return
        name = self.nodes[can_id & NODE_MASK]
        if can_id & FUNCTION_MASK == EMCY_BASE:
            code = int(data[0]) | int(data[1]) << 8
            _append(self.emcy, {"time_us": t, "node": name, "code": f"0x{code:04X}", "register": int(data[2])})
            return
        state = NMT_STATES.get(int(data[0]) & 0x7F, f"0x{int(data[0]):02X}")
        beats = self.heartbeats.setdefault(name, {"count": 0, "state": None})
        beats["count"] += 1
        if beats["state"] != state:
            _append(self.states, {"time_us": t, "node": name, "state": state})
            beats["state"] = state

    def shift_times(self, origin: int) -> None:
        """Times from the log's first frame, as every time in the report."""
        for item in [*self.nmt, *self.emcy, *self.states]:
            item["time_us"] -= origin

    def report(self) -> dict[str, Any]:
        for items in (self.nmt, self.emcy, self.states):  # noted message by message within a batch
            items.sort(key=lambda item: item["time_us"])
        return {
            "heartbeats": self.heartbeats,
            "nmt_states": self.states,
            "nmt_commands": self.nmt,
            "emcy": self.emcy,
            "sdo_frames": self.sdo,
            "other_service_frames": self.other,
        }


def _append(items: list[dict[str, Any]], item: dict[str, Any]) -> None:
    if len(items) < MAX_LISTED:
        items.append(item)
