"""runtime.json: everything a live master or the simulator needs, read back by netcfg.runtime.

Convention: every time is an integer number of nanoseconds in a key ending in "_ns" (exact, as inside the
compiler); floats appear only for signal scale/offset/min/max and cable lengths. An exact Ethernet rate is a
[numerator, denominator] pair, because 15 kHz has no exact period in ns. Lists keep the spec's order (buses,
nodes, messages per bus with the implicit SYNC/heartbeats where the resolver put them), so the file is
byte-identical across builds. A protocol's own section (FTT-CAN's schedule, an EtherCAT segment) is its layer's
(Protocol.runtime_section), never recomputed here.

CANopen facts a live master needs come from where the other artifacts take them, so they cannot disagree: the
file names from netcfg.protocols.canopen.dcf, the PDO COB-ID values from netcfg.cia301 (as the DCFs), the identity and
PDO counts from the node's device profile (built-in or EDS). Keys added later within version 1 only ever add
information (see netcfg.runtime).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from netcfg import cia301, jsontext, links, model, protocols
from netcfg.protocols.canopen import dcf as canopen_dcf
from netcfg.records import same_named
from netcfg.runtime import interpolation_period
from netcfg.runtime.schema import check_document
from netcfg.timing import flows
from netcfg.timing.clocks import DEFAULT_TOLERANCE_PPM

FORMAT = "netcfg-runtime"
VERSION = 1  # bump when a key changes meaning or disappears; netcfg.runtime.SUPPORTED_VERSIONS must follow

INTERPOLATION = 0x60C2  # CiA 402 interpolation time period: sub 1 value (UNSIGNED8), sub 2 index (INTEGER8)
CIA402 = 402  # CiA 301 7.5.2.1: device type 0x1000, low 16 bits = the device profile number


def emit(m: model.Model, report: dict[str, Any]) -> dict[str, bytes]:
    doc = runtime_document(m, report)
    problems = check_document(doc, strict=True)  # what netcfg.runtime.load accepts, checked at the source
    if problems:
        raise ValueError(f"runtime.json would not load: {problems[0]}")
    text = jsontext.dumps(doc, indent=2, sort_keys=True, ensure_ascii=False) + "\n"
    return {"runtime.json": text.encode("utf-8")}


def runtime_document(m: model.Model, report: dict[str, Any]) -> dict[str, Any]:
    wcrt = _report_wcrt(report)
    plain = _report_wcrt(report, "wcrt_plain_can_ns")
    flow_rows = {f["name"]: f for f in report.get("flows", [])}
    files = canopen_dcf.file_names(m)
    return {
        "format": FORMAT,
        "version": VERSION,
        "system": m.system,
        # lets a master refuse a runtime.json built from another revision of the spec
        "spec_sha256": hashlib.sha256(Path(m.file).read_bytes()).hexdigest(),
        "buses": [_bus(m, b, _sync_completion(report, b.name)) for b in m.buses.values()],
        "nodes": [_node(m, n, files) for n in m.nodes.values()],
        "messages": [
            _message(m, msg, wcrt.get(msg.name), plain.get(msg.name, wcrt.get(msg.name)))
            for b in m.buses.values()
            for msg in b.messages
        ],
        "triggers": [_trigger(t) for t in m.triggers.values()],
        "flows": [_flow(f, flow_rows.get(f.name)) for f in m.flows.values()],
    }


TASK_KEYS = "name period_ns offset_ns wcet_ns bcet_ns trigger on_message sync_bus"  # a task's, as the model's


def _report_wcrt(report: dict[str, Any], key: str = "wcrt_ns") -> dict[str, int | None]:
    """The analysed worst-case response times in integer ns (`key`: another exact bound of the rows)."""
    rows = (row for b in report.get("buses", []) for row in b.get("messages", []))
    return {row["name"]: row.get(key) for row in rows if key in row}


def _sync_completion(report: dict[str, Any], bus: str) -> int | None:
    """The analysed worst case from SYNC to the last synchronous TPDO's end (the SYNC-cycle analysis), in ns."""
    for row in report.get("buses", []):
        if row.get("name") == bus and row.get("sync"):
            us = row["sync"].get("worst_completion_us")  # the report's microseconds, to 3 decimals: whole ns
            return None if us is None else round(us * 1000)
    return None


def _bus(m: model.Model, b: model.Bus, sync_completion_ns: int | None = None) -> dict[str, Any]:
    canopen = _canopen(b.canopen)
    if canopen is not None:
        canopen["sync_completion_ns"] = sync_completion_ns  # the bound a master's read time is held against
    # CAN FD keys only on CAN FD buses and frames: files of the other protocols stay as they were
    fd = {"data_bitrate": b.data_bitrate} if links.of(b).data_phase else {}
    # the error model only where the spec states one: files of error-free buses stay as they were
    errors = {"errors": {"burst": b.errors.burst, "interval_ns": b.errors.interval_ns}} if b.errors else {}
    # the senders' clock tolerance only where the spec changes the default, for the same reason
    tolerance = {"clock_tolerance_ppm": b.clock_tolerance_ppm} if b.clock_tolerance_ppm != DEFAULT_TOLERANCE_PPM else {}
    return {
        **fd,
        **errors,
        **tolerance,
        "name": b.name,
        "protocol": b.protocol,
        "link": links.of(b).name,  # what the runtime reads to tell CAN frames from datagrams
        "bitrate": b.bitrate,
        "id_bits": b.id_bits,
        "nodes": list(b.nodes),
        "canopen": canopen,
        "ftt": None,  # every bus has the key; an FTT-CAN bus's protocol fills it in
        "ethernet": _ethernet(m, b) if links.of(b).switched else None,
        # the protocol's own section (FTT-CAN's schedule, an EtherCAT segment's), only on its buses: files of the
        # other protocols stay as they were
        **protocols.of(b).runtime_section(b),
    }


def _canopen(co: model.CanopenBus | None) -> dict[str, Any] | None:
    if co is None:
        return None
    return same_named(
        co, "sync_period_ns sync_window_ns read_window_ns sync_producer sync_id master_jitter_ns sync_overflow"
    )


def _ethernet(m: model.Model, b: model.Bus) -> dict[str, Any]:
    """The cabling and every transmit queue's depth (the nodes' NICs, the switches' egress ports)."""
    return {
        "switches": [_switch(s) for s in b.switches],
        "nics": [{"node": n, "queue": m.nodes[n].nic_queue} for n in b.nodes],
    }


def _switch(s: model.Switch) -> dict[str, Any]:
    return {
        **same_named(s, "name latency_ns queue"),
        "ports": [
            {"port": p, "to": s.ports[p], "cable_m": s.cables_m.get(p, 0.0), "queue": s.queues[p]}
            for p in sorted(s.ports)
        ],
    }


def _node(m: model.Model, n: model.Node, files: dict[tuple[str, str], dict[str, str]]) -> dict[str, Any]:
    out = _node_keys(m, n, files)
    if n.actuator is not None:  # written only for an actuator: every other node's keys stay as they were
        out["actuator"] = n.actuator
    return out


def _node_keys(m: model.Model, n: model.Node, files: dict[tuple[str, str], dict[str, str]]) -> dict[str, Any]:
    dev = n.device
    # a node on several CANopen buses has one folder of files per bus (canopen/<bus>/); these keys then stay null
    own = [paths for (_, name), paths in files.items() if name == n.name]
    paths = own[0] if len(own) == 1 else {}
    return {
        **same_named(n, "name node_id role ip heartbeat_ns heartbeat_timeout_ns on_loss on_emcy on_reboot"),
        **same_named(n, "sdo_timeout_ns sdo_retries safe_stop tx_delay_ns rx_delay_ns"),
        "buses": list(n.buses),
        "device": n.device.name if n.device is not None else None,
        "tx_queue": same_named(n.tx_queue, "policy depth on_full"),
        "tasks": [same_named(t, TASK_KEYS) for t in n.tasks.values()],
        "identity": None
        if dev is None
        else {"vendor_id": dev.vendor_id, "product_code": dev.product_code, "revision": dev.revision},
        "eds": paths.get("eds"),
        "dcf": paths.get("dcf"),
        "rpdo_count": None if dev is None else dev.rpdo_count,
        "tpdo_count": None if dev is None else dev.tpdo_count,
        "sdo_init": _sdo_init(m, n),
    }


def _sdo_init(m: model.Model, n: model.Node) -> list[dict[str, Any]]:
    """Start-up SDO writes the model determines: the communication objects the spec sets (below), then the CiA 402
    interpolation time period (_interpolation_init)."""
    return _communication_init(m, n) + _interpolation_init(m, n)


def _communication_init(m: model.Model, n: model.Node) -> list[dict[str, Any]]:
    """CiA 301 objects the spec sets and the device lets a master write: the producer heartbeat time (0x1017, ms),
    the synchronous window (0x1007, us) and the SYNC counter overflow value (0x1019) of the node's CANopen bus.
    A device without the object (or with it read-only) is left as it is: its DCF says the same."""
    dev = n.device
    if dev is None:
        return []
    buses = [co for b in n.buses if (co := m.buses[b].canopen) is not None]
    co = buses[0] if len(buses) == 1 else None
    wanted = [(0x1017, None if n.heartbeat_ns is None else n.heartbeat_ns // 1_000_000)]
    if co is not None:
        wanted.append((0x1007, None if co.sync_window_ns is None else co.sync_window_ns // 1000))
        wanted.append((0x1019, co.sync_overflow or None))
    out = []
    for index, value in wanted:
        entry = dev.lookup(index, 0)
        if value is not None and entry is not None and entry.writable:
            out.append({"index": index, "sub": 0, "data_type": entry.data_type, "value": value})
    return out


def _interpolation_init(m: model.Model, n: model.Node) -> list[dict[str, Any]]:
    """A CiA 402 drive interpolates its set-points over
    the interpolation time period 0x60C2 (CiA 402 / IEC 61800-7-201: period = sub 1 value * 10^(sub 2 index) s),
    which in the cyclic synchronous modes is the SYNC period that delivers them (CiA 402, cyclic synchronous
    position/velocity/torque modes). The spec cannot state the modes of operation, so 0x6060 is never written here.
    A CiA 402 device: its profile has a writable 0x60C2:1 and :2, and a device type (0x1000), where the profile
    knows it, naming profile 402. The SYNC period: the one of the node's CANopen buses, when they agree."""
    dev = n.device
    if dev is None:
        return []
    device_type = dev.lookup(0x1000, 0)
    if device_type is not None and device_type.default is not None and device_type.default & 0xFFFF != CIA402:
        return []
    value, index = dev.lookup(INTERPOLATION, 1), dev.lookup(INTERPOLATION, 2)
    if value is None or index is None or not (value.writable and index.writable):
        return []
    periods = {co.sync_period_ns for b in n.buses if (co := m.buses[b].canopen) is not None}
    period = interpolation_period(periods.pop()) if len(periods) == 1 else None
    if period is None:
        return []
    return [
        {"index": INTERPOLATION, "sub": 1, "data_type": value.data_type, "value": period[0]},
        {"index": INTERPOLATION, "sub": 2, "data_type": index.data_type, "value": period[1]},
    ]


def _message(m: model.Model, msg: model.Message, wcrt_ns: int | None, wcrt_unsync_ns: int | None) -> dict[str, Any]:
    fd = {"fd": True, "brs": msg.brs, "frame_size": msg.frame_size} if msg.fd else {}
    remote = {"remote": True} if msg.remote else {}  # a remote frame: RTR, no data (size 0)
    return {
        **fd,
        **remote,
        **same_named(msg, "name bus producer id extended size kind period_ns interval_ns offset_ns deadline_ns"),
        **same_named(msg, "jitter_ns window ftt_id implicit"),
        "consumers": list(msg.consumers),
        "rate_hz": None if msg.rate_hz is None else [msg.rate_hz.numerator, msg.rate_hz.denominator],
        "udp": None if msg.udp_ports is None else {"src_port": msg.udp_ports[0], "dst_port": msg.udp_ports[1]},
        "pdo": _pdo(msg),
        "signals": [_signal(s) for s in msg.signals],
        "wcrt_ns": wcrt_ns,  # the analysis' bound, for a simulator or master to compare against
        "wcrt_unsync_ns": wcrt_unsync_ns,  # the bound with the bus run as free-running CAN
        "sent_by": list(flows.sending_tasks(m, msg)),  # tasks that send it as they finish; else it runs free
    }


def _pdo(msg: model.Message) -> dict[str, Any] | None:
    p = msg.pdo
    if p is None:
        return None
    return {
        **same_named(p, "kind number transmission inhibit_100us event_timer_ms sync_start"),
        "node": p.node,
        "cob_id": cia301.pdo_cob_id(p.kind, msg.id, msg.extended),  # the DCF's value: the same function
        "entries": [same_named(e, "index sub bits name data_type") for e in p.entries],
    }


def _signal(s: model.Signal) -> dict[str, Any]:
    return {
        **same_named(s, "name start_bit bits signed unit"),
        "float": s.is_float,
        "scale": float(s.scale),
        "offset": float(s.offset),
        "min": None if s.minimum is None else float(s.minimum),
        "max": None if s.maximum is None else float(s.maximum),
        # written only when used, so that runtime configurations without them stay as they were
        **({"byte_order": "big_endian"} if s.big_endian else {}),
        **({"mux": s.mux, "mux_values": list(s.mux_values)} if s.mux is not None else {}),
        **({"enum": [[raw, name] for raw, name in s.choices]} if s.choices else {}),
    }


def _trigger(t: model.Trigger) -> dict[str, Any]:
    return {**same_named(t, "name bus ftt_id period_ns interval_ns offset_ns"), "tasks": list(t.tasks)}


def _flow(f: model.Flow, row: dict[str, Any] | None) -> dict[str, Any]:
    unsync = (row or {}).get("unsynchronised")
    return {
        "name": f.name,
        "steps": [{"kind": s.kind, "refs": list(s.refs)} for s in f.steps],
        "deadline_ns": f.deadline_ns,
        # the analysis' bounds, for comparison with measured latencies
        "latency_min_ns": row["latency_ns"][0] if row else None,
        "latency_max_ns": row["latency_ns"][1] if row else None,
        # the same without SYNC alignment, for a simulator that runs the bus unsynchronised
        "unsync_latency_min_ns": unsync["latency_ns"][0] if unsync else None,
        "unsync_latency_max_ns": unsync["latency_ns"][1] if unsync else None,
    }
