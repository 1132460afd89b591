"""The PDOs of a bus.yml's slaves as the spec's messages: dcfgen's numbering of 'cob_id: auto', what each
PDO keeps of its DCF slot, its COB-ID, timing and mapping (the rules are in netcfg.importers.bus_yml's docstring).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from netcfg import cia301
from netcfg.diagnostics import Collector
from netcfg.importers import ImportOptions
from netcfg.importers import Path as SpecPath
from netcfg.importers.bus_yml_dcf import DeviceFile, Slot
from netcfg.importers.bus_yml_keys import (
    FIRST_AUTO_COB_ID,
    LAST_AUTO_COB_ID,
    MAPPING_KEYS,
    PDO_KEYS,
    PDO_NOTE_KEYS,
    BusPath,
    default_timing,
    duration,
    duration_ns,
    safe_name,
)
from netcfg.importers.bus_yml_read import BusYmlReader, Val
from netcfg.spec.names import is_name


@dataclass(frozen=True)
class PdoItem:
    """One PDO of a slave as the bus.yml (or, for from_dcf, only its DCF) configures it."""

    slave: str  # as named in the bus.yml
    node: str  # as named in the spec
    kind: str
    number: int
    val: Val
    cfg: dict[str, Val]
    slot: Slot | None
    node_id: int
    master: str
    auto_id: int | None  # dcfgen's COB-ID for 'cob_id: auto' on PDOs 5+
    from_dcf: bool = False


class BusYmlPdos(BusYmlReader):
    """The messages the slaves' PDOs become, and dcfgen's 'cob_id: auto' allocation across the file."""

    def __init__(self, path: Path, options: ImportOptions, diags: Collector) -> None:
        super().__init__(path, options, diags)
        self.ros = False  # ros2_canopen dialect (defaults/nodes)
        self.messages: list[dict[str, Any]] = []
        self.auto_cob_id = FIRST_AUTO_COB_ID
        self.auto_ids: dict[tuple[str, str, int], int] = {}
        self.sync_us = 0

    def pdo_entries(self, cfg: dict[str, Val], kind: str, report: bool) -> list[tuple[int, Val, dict[str, Val]]]:
        """(number, its value, its keys) of one node's rpdo/tpdo section, in file order."""
        section = cfg.get(kind)
        if section is None:
            return []
        if not isinstance(section.value, dict):
            if report:
                self.err(
                    "bus-yml-value", f"'{kind}' maps PDO numbers to settings, e.g. '1: {{enabled: true}}'", section.path
                )
            return []
        out = []
        for key, val in self.sub(section.value, section.path).items():
            if not key.isdigit() or not 1 <= int(key) <= 512:
                if report:
                    self.err("bus-yml-value", f"'{kind}' keys are PDO numbers 1..512, not '{key}'", val.path, True)
                continue
            pdo = val.value if val.value is not None else {}
            if not isinstance(pdo, dict):
                if report:
                    self.err("bus-yml-value", f"{kind} {key} must be a mapping of PDO settings", val.path)
                continue
            out.append((int(key), val, self.sub(pdo, val.path)))
        return out

    def allocate(self, name: str, cfg: dict[str, Val]) -> None:
        """Replay dcfgen's numbering of 'cob_id: auto' on PDOs 5+ (rpdo section first, then tpdo; enabled or not)."""
        for kind in ("rpdo", "tpdo"):
            entries = self.pdo_entries(cfg, kind, report=False)
            for number, val, pdo in sorted(entries, key=lambda e: e[0]) if self.ros else entries:
                if number > 4 and "cob_id" in pdo and pdo["cob_id"].value == "auto":
                    if self.auto_cob_id > LAST_AUTO_COB_ID:
                        self.err(
                            "bus-yml-pdo", "no 11-bit COB-IDs left for 'cob_id: auto' (dcfgen stops too)", val.path
                        )
                        return
                    self.auto_ids[(name, kind, number)] = self.auto_cob_id
                    self.auto_cob_id += 1

    def pdos(
        self, name: str, own: BusPath, cfg: dict[str, Val], added: tuple[DeviceFile, int, str], master: str
    ) -> None:
        device, nid, node = added
        for kind in ("rpdo", "tpdo"):
            listed = set()
            for number, val, pdo in self.pdo_entries(cfg, kind, report=True):
                listed.add(number)
                slot = device.slot(kind, number, nid)
                auto = self.auto_ids.get((name, kind, number))
                self.pdo(PdoItem(name, node, kind, number, val, pdo, slot, nid, master, auto))
            for number in device.slots(kind):  # dcfgen keeps what the DCF enables and the bus.yml does not mention
                slot = device.slot(kind, number, nid)
                if number in listed or slot is None or slot.cob_id is None or slot.cob_id & cia301.PDO_INVALID:
                    continue
                if not slot.mapping:
                    continue
                self.warn(
                    "bus-yml-pdo",
                    f"{kind.upper()}{number} of node '{name}' is not in {self.name} but its dcf enables it; dcfgen "
                    f"leaves it on the bus, so netcfg imports it (add '{kind}: {{{number}: {{enabled: false}}}}' if "
                    "it should be off)",
                    own,
                    key=True,
                )
                self.pdo(PdoItem(name, node, kind, number, Val({}, own), {}, slot, nid, master, None, from_dcf=True))

    def pdo(self, p: PdoItem) -> None:
        label = f"{p.kind} {p.number} of node '{p.slave}'"
        cfg, val, slot = p.cfg, p.val, p.slot
        kept: list[str] = []
        self.keys(cfg, PDO_KEYS, set(), label, kept)
        enabled = cfg.get("enabled", Val(True, val.path))  # dcfgen: enabled unless it says false
        if not isinstance(enabled.value, bool):
            self.err("bus-yml-value", f"'enabled' of {label} must be true or false", enabled.path)
            return
        if not enabled.value:
            return
        if slot is None:
            comm = cia301.pdo_comm_index(p.kind, p.number)
            self.err(
                "bus-yml-pdo",
                f"{label}: its dcf has no {p.kind.upper()}{p.number} (no object 0x{comm:04X})",
                val.path,
                True,
            )
            return
        cob_id = self.cob_id(p, label)
        if cob_id is None:
            return
        cob_id &= ~cia301.PDO_NO_RTR  # bit 30 only forbids remote requests; netcfg's DCFs set it on every TPDO
        tt_val = cfg.get("transmission")
        if tt_val is not None:
            tt = self.integer(tt_val, f"transmission of {label}", 0, 255)
            if tt is None:
                return
        else:
            tt = slot.transmission if slot.transmission is not None else 0  # dcfgen's PDO starts at type 0
        mpath: SpecPath = ("messages", len(self.messages))
        self.origin[mpath] = val.path
        pdo: dict[str, Any] = {p.kind: p.number, "transmission": tt}
        if tt_val is not None:
            self.link((*mpath, "pdo", "transmission"), tt_val.path)
        given: dict[str, int | None] = {}
        for key in ("inhibit_time", "event_timer", "sync_start"):
            v = cfg.get(key)
            if v is None:
                continue
            given[key] = self.integer(v, f"{key} of {label}", 0, 240 if key == "sync_start" else 0xFFFF)
            if p.kind == "rpdo" and key != "event_timer" and given[key]:
                # dcfgen gives these to the master's mirrored TPDO; netcfg times the master's sends itself
                self.warn("bus-yml-pdo", f"{key} {given[key]} of {label} (the master's side) is not modelled", v.path)
                kept.append(f"{key}: {given[key]}")
                given[key] = None
        inhibit = given.get("inhibit_time", slot.inhibit_100us)
        event = given.get("event_timer", slot.event_timer_ms)
        sync_start = given.get("sync_start", slot.sync_start)
        if inhibit:
            pdo["inhibit"] = f"{inhibit * 100} us"  # CiA 301: multiples of 100 us
            self.link((*mpath, "pdo", "inhibit"), cfg["inhibit_time"].path if "inhibit_time" in cfg else val.path)
        if event:
            pdo["event_timer"] = f"{event} ms"
            self.link((*mpath, "pdo", "event_timer"), cfg["event_timer"].path if "event_timer" in cfg else val.path)
        if sync_start and 1 <= tt <= 240:
            pdo["sync_start"] = sync_start
        elif sync_start:
            kept.append(f"sync_start: {sync_start} (acts only with transmission types 1-240)")
        if "event_deadline" in cfg:
            kept.append(f"event_deadline: {cfg['event_deadline'].value} (the slave's RPDO deadline monitoring)")
        pdo["map"] = self.map_entries(cfg.get("mapping"), slot, label, mpath)
        if not pdo["map"]:
            if "mapping" in cfg and isinstance(cfg["mapping"].value, list) and not cfg["mapping"].value:
                self.warn(
                    "bus-yml-pdo", f"{label} maps nothing: dcfgen drops it from the master; so does netcfg", val.path
                )
            del self.origin[mpath]
            return
        note = self.note(val.path) if not p.from_dcf and val.path[:1] != ("defaults",) else {}
        for key in note:
            if key not in PDO_NOTE_KEYS:
                self.warn("bus-yml-note", f"unknown '# netcfg:' key '{key}' ignored", val.path, key=True)
        named = note.get("message", "")
        message: dict[str, Any] = {
            "name": named if is_name(named) else safe_name(f"{p.node}_{p.kind}{p.number}", "pdo")
        }
        if p.kind == "tpdo":
            message.update(producer=p.node, consumers=[p.master])
        else:
            message.update(producer=p.master, consumers=[p.node])
        if cob_id != cia301.default_pdo_cob_id(p.kind, p.number, p.node_id):
            message["id"] = cob_id & cia301.COB_ID_MASK  # 11-bit ids keep bits 11-28: resolve rejects them
            self.link((*mpath, "id"), cfg["cob_id"].path if "cob_id" in cfg else val.path)
        if cob_id & cia301.PDO_EXTENDED:
            message["extended"] = True
        if p.from_dcf:
            lines = [f"{p.kind}.{p.number} of {p.slave}: not in {self.name}, enabled by its dcf (dcfgen keeps it)"]
        else:
            lines = [self.where(val.path) + (f" (for {p.slave})" if val.path[:1] == ("defaults",) else "")]
        lines.extend(self.timing(message, p.kind, tt, event, inhibit, note, val.path))
        message["pdo"] = pdo
        if kept:
            lines.append("kept from the bus.yml: " + "; ".join(kept))
        self.comments[mpath] = "\n".join(lines)
        self.messages.append(message)

    def cob_id(self, p: PdoItem, label: str) -> int | None:
        """The COB-ID dcfgen gives the PDO (flags included), or None when it stays off (warned) or is wrong."""
        cob = p.cfg.get("cob_id")
        if cob is None:  # dcfgen keeps the DCF's COB-ID
            value = p.slot.cob_id if p.slot is not None else None
            if value is None or value & cia301.PDO_INVALID:
                self.warn(
                    "bus-yml-pdo",
                    f"{label} is enabled without a cob_id, and its dcf's COB-ID is invalid (bit 31): dcfgen leaves it "
                    "off, so netcfg skips it; add 'cob_id: auto'",
                    p.val.path,
                    key=True,
                )
                return None
            return value
        if cob.value == "auto":
            return cia301.default_pdo_cob_id(p.kind, p.number, p.node_id) if p.number <= 4 else p.auto_id
        value = self.integer(cob, f"cob_id of {label} ('auto' or a number)", 1, 0xFFFFFFFF)
        if value is not None and value & cia301.PDO_INVALID:
            self.warn("bus-yml-pdo", f"cob_id of {label} has bit 31 (PDO invalid) set: dcfgen leaves it off", cob.path)
            return None
        return value

    def timing(
        self,
        message: dict[str, Any],
        kind: str,
        tt: int,
        event: int | None,
        inhibit: int | None,
        note: dict[str, str],
        where: BusPath,
    ) -> list[str]:
        """Keys saying how often the message goes out (see the module docstring); -> comment lines."""
        if note.get("type") in ("periodic", "sporadic", "on-demand"):
            message["type"] = note["type"]
            if note["type"] == "periodic" and note.get("period_ns", "").isdigit():
                message["period"] = duration_ns(int(note["period_ns"]))
            if note["type"] == "sporadic" and note.get("min_interarrival_ns", "").isdigit():
                message["min_interarrival"] = duration_ns(int(note["min_interarrival_ns"]))
            return []
        kind_of, period, interval = default_timing(kind, tt, event, inhibit, self.sync_us * 1000)
        if kind == "tpdo":
            if kind_of != "on-demand":
                return []  # netcfg derives the timing from the transmission type, event timer and inhibit time
            message["type"] = "on-demand"
            # with an event timer only an inhibit time can bound it (cia301.tpdo_timing), without one a min_interarrival
            fix = "the TPDO an inhibit_time" if event else "the spec's message a min_interarrival"
            self.warn(
                "bus-yml-timing",
                f"TPDO '{message['name']}' (transmission type {tt}) has no inhibit time: netcfg cannot bound how "
                "often it is sent on events and leaves those out of the load (type: on-demand; an event timer's own "
                f"sends are counted); give {fix} if it is sent on events in operation",
                where,
                key=True,
            )
            if event:
                return ["sent on events with no bound on their rate (not in the load) and every event_timer"]
            return ["sent on events only, with no bound on its rate: on-demand (not in the steady-state load)"]
        if kind_of == "sporadic":
            message["min_interarrival"] = duration((interval or 0) // 1000)
            return ["acyclic synchronous (type 0): the master sends it at most once per SYNC"]
        message["period"] = duration((period or 0) // 1000)
        if 1 <= tt <= 240:
            return [f"the master sends it on every {tt}. SYNC"]
        if event:
            return ["the master sends it every event_timer (dcfgen gives the master's mirrored TPDO that timer)"]
        return ["event-driven, no event timer: assumed written once per SYNC period, as ros2_canopen's drivers do"]

    def map_entries(self, val: Val | None, slot: Slot, label: str, mpath: SpecPath) -> list[Any]:
        out: list[Any] = []
        if val is None:  # dcfgen keeps the DCF's mapping
            return [index if sub == 0 else f"0x{index:04X}:{sub}" for index, sub in slot.mapping]
        if not isinstance(val.value, list):
            self.err("bus-yml-value", f"'mapping' of {label} is a list of {{index, sub_index}}", val.path)
            return out
        shape = f"a mapping entry of {label} is {{index: 0x6041, sub_index: 0}}"
        for ipath, _, index, sub in self.objects(val, MAPPING_KEYS, f"a mapping entry of {label}", shape, "mapping"):
            ref: Any = index if sub == 0 else f"0x{index:04X}:{sub}"
            name = self.note(ipath, key=False).get("name", "")
            if is_name(name):
                ref = {"object": f"0x{index:04X}:{sub}", "name": name}
            self.link((*mpath, "pdo", "map", len(out)), ipath)
            out.append(ref)
        return out

