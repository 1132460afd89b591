"""canopen/bus.yml: every CANopen bus as a Lely dcfgen / ros2_canopen bus configuration.

One file per CANopen bus: canopen/bus.yml, or canopen/<bus>.bus.yml when the system has several. It is written in
dcfgen's own layout (options, master, one mapping per slave), which dcfgen reads directly and ros2_canopen's
`generate_dcf` CMake macro too; its `cogen_dcf` macro wants the slaves under `nodes:` instead.

- master: node_id, baudrate (kbit/s), sync_period and sync_window (us), sync_overflow, heartbeat_producer (ms).
- every other node with a node id: `dcf` = the EDS netcfg generates next to this file (canopen_dcf's folders: a node
  on several CANopen buses has canopen/<bus>/<node>.eds), node_id, heartbeat_producer, and every PDO slot the device
  has: the configured ones with enabled, cob_id ('auto' when it is the CiA 301 default, else the number, bit 29 for
  29-bit ids), transmission, inhibit_time (100 us) and event_timer (ms) where the device has them, sync_start, and
  mapping as {index, sub_index}; the others `enabled: false`, as netcfg's DCFs disable them.
- `options: {dcf_path: "."}`: ros2_canopen's CMake macros replace "@BUS_CONFIG_PATH@" by "." anyway, and plain
  dcfgen takes "." as it is.
- What a bus.yml cannot say goes into `# netcfg:` comments, which dcfgen and ros2_canopen ignore and
  `netcfg import bus-yml` reads back: the system, bus and master names and the read window (header), a message name
  that is not <node>_<tpdo|rpdo><n>, timing the importer would not derive from the transmission type, signal names
  that are not the object's name, and the built-in profile a slave's EDS was generated from. Messages the format has
  no place for (plain CAN frames, PDOs between two slaves) are listed in the header comment.

The file is rendered from templates/bus_yml.j2 (one template per file kind, as the other emitters): every name is a
checked spec name and every value a number, so the template never needs YAML quoting rules.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from netcfg import cia301
from netcfg.emit import joint_scaling
from netcfg.emit.bus_yml_spec import SPEC_NOTE, spec_notes
from netcfg.importers.bus_yml_keys import default_timing, safe_name
from netcfg.model import Bus, Joint, Message, Model, Node
from netcfg.resolve import snake
from netcfg.runtime.pdos import PdoEntry
from netcfg.templating import render

TEMPLATE = "bus_yml.j2"


@dataclass(frozen=True)
class MapView:
    index: str
    sub: int
    note: str


@dataclass(frozen=True)
class PdoView:
    number: int
    enabled: bool
    note: str = ""
    cob_id: str = ""
    transmission: int = 0
    inhibit_time: int | None = None
    event_timer: int | None = None
    sync_start: int | None = None
    mapping: tuple[MapView, ...] = ()


@dataclass(frozen=True)
class SlaveView:
    name: str
    note: str
    comments: tuple[str, ...]
    dcf: str | None
    node_id: int
    heartbeat: int | None
    rpdo: tuple[PdoView, ...]
    tpdo: tuple[PdoView, ...]
    heartbeat_multiplier: str | None = None  # only when the consumer time is not dcfgen's default 3 x
    # a drive that moves a joint: ros2_canopen's CiA 402 driver (driver, package) and its scaling, as (key, value)
    driver: tuple[tuple[str, str], ...] = ()
    scaling: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class BusView:
    header: tuple[str, ...]
    annotation: str
    master_id: int
    master_heartbeat: int | None
    baudrate: int
    sync_period: int
    sync_window: int | None
    slaves: tuple[SlaveView, ...]
    sync_overflow: int | None = None  # CiA 301 0x1019, when SYNC carries a counter


def emit(model: Model, report: dict[str, Any]) -> dict[str, bytes]:
    buses = [b for b in model.buses.values() if b.canopen is not None]
    files: dict[str, bytes] = {}
    for bus in buses:
        view = _bus_view(model, bus, buses)
        if view is not None:
            files[bus_yml_name(model, bus.name)] = render(TEMPLATE, b=view)
    return files


def bus_yml_name(model: Model, bus: str) -> str:
    """The bus's file: canopen/bus.yml, or canopen/<bus>.bus.yml when the system has several CANopen buses."""
    several = sum(1 for b in model.buses.values() if b.canopen is not None) > 1
    return f"canopen/{bus}.bus.yml" if several else "canopen/bus.yml"


def _note(**items: object) -> str:
    """A `# netcfg:` comment for the end of a line, or nothing."""
    words = [f"{k}={v}" for k, v in items.items() if v is not None]
    return f"  # netcfg: {' '.join(words)}" if words else ""


def _bus_view(model: Model, bus: Bus, buses: list[Bus]) -> BusView | None:
    co = bus.canopen
    assert co is not None
    on_bus = [model.nodes[n] for n in bus.nodes if model.nodes[n].node_id is not None]
    masters = [n for n in on_bus if n.role == "master"] or [n for n in on_bus if n.name == co.sync_producer]
    if not masters:  # resolve refuses a CANopen bus without a master or SYNC producer
        return None
    master = masters[0]
    assert master.node_id is not None
    header = [
        f"CANopen bus {bus.name} of {model.system}: Lely dcfgen / ros2_canopen bus configuration, written by netcfg.",
        "The dcf files are the EDS netcfg generates next to this file; '# netcfg:' comments are for netcfg import.",
    ]
    notes, crossing = spec_notes(model, bus)
    left_out = [*_left_out(model, bus, master), *crossing, *_other_axes(model, bus)]
    header.extend(f"not expressible here, kept in the netcfg spec: {text}" for text in left_out)
    header.extend(f"{SPEC_NOTE} {note}" for note in notes)
    annotation = {
        "system": model.system,
        "bus": bus.name,
        "master": master.name,
        "read_window_ns": co.read_window_ns,
        "sync_id": f"0x{co.sync_id:X}" if co.sync_id != cia301.SYNC_ID else None,
        "sync_producer": co.sync_producer if co.sync_producer != master.name else None,
    }
    joints = joint_scaling.bus_joints(model, bus)
    slaves = tuple(
        _slave_view(model, bus, node, buses, master, joints.get(node.name))
        for node in on_bus
        if node is not master and node.role != "master"
    )
    return BusView(
        header=tuple(header),
        annotation=_note(**annotation).removeprefix("  # netcfg: "),
        master_id=master.node_id,
        master_heartbeat=_ms(master.heartbeat_ns),
        baudrate=bus.bitrate // 1000,
        sync_period=co.sync_period_ns // 1000,
        sync_window=co.sync_window_ns // 1000 if co.sync_window_ns is not None else None,
        sync_overflow=co.sync_overflow or None,
        slaves=slaves,
    )


def _ms(ns: int | None) -> int | None:
    return ns // 1_000_000 if ns else None


def _left_out(model: Model, bus: Bus, master: Node) -> list[str]:
    out = []
    for m in bus.messages:
        if m.implicit is not None:
            continue
        if m.pdo is None:
            out.append(f"message {m.name} (id 0x{m.id:X}) is no PDO")
        elif m.pdo.kind == "tpdo" and any(c != master.name for c in m.consumers):
            others = ", ".join(c for c in m.consumers if c != master.name)
            out.append(f"{m.name} also goes to {others} (a PDO between slaves)")
        elif m.pdo.kind == "rpdo" and m.producer != master.name:
            out.append(f"{m.name} is sent by {m.producer}, not by the master")
    return out


def _other_axes(model: Model, bus: Bus) -> list[str]:
    """Joints on a drive's second axis or beyond: ros2_canopen's bus.yml scales a drive, not an axis."""
    return [
        f"joint {j.name} (axis {j.axis} of {j.node}): its scaling, per axis"
        for j in model.joints.values()
        if j.axis != 1 and joint_scaling.joint_bus(model, j) is bus
    ]


def _ros_driver(joint: Joint | None) -> tuple[tuple[tuple[str, str], ...], tuple[tuple[str, str], ...]]:
    """(driver and package, scaling) of a drive that moves a joint, as the bus.yml writes them; nothing otherwise."""
    if joint is None:
        return (), ()
    driver = (("driver", f'"{joint_scaling.DRIVER}"'), ("package", f'"{joint_scaling.PACKAGE}"'))
    return driver, tuple((key, _yaml_float(value)) for key, value in joint_scaling.scaling(joint))


def _yaml_float(value: float) -> str:
    """The shortest text that reads back as the same float, with the dot YAML 1.1 (PyYAML, so dcfgen) needs to
    take an exponent's number as a float rather than a string."""
    text = repr(value)
    mantissa, e, exponent = text.partition("e")
    return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text


def _slave_view(
    model: Model, bus: Bus, node: Node, buses: list[Bus], master: Node, joint: Joint | None = None
) -> SlaveView:
    assert node.node_id is not None and bus.canopen is not None
    dev = node.device
    comments: list[str] = []
    dcf = None
    if dev is not None:
        on = sum(1 for b in buses if node.name in b.nodes)
        dcf = f"{node.name}.eds" if on == 1 else f"{bus.name}/{node.name}.eds"  # canopen_dcf's folders
    else:
        comments.append(f"{node.name} has no device profile in netcfg: give its EDS as 'dcf'")
    slots: dict[tuple[str, int], Message] = {}
    for m in bus.messages:
        p = m.pdo
        if p is not None and (m.producer == node.name if p.kind == "tpdo" else node.name in m.consumers):
            slots.setdefault((p.kind, p.number), m)
    pdos: dict[str, tuple[PdoView, ...]] = {}
    for kind in ("rpdo", "tpdo"):
        count = (dev.rpdo_count if kind == "rpdo" else dev.tpdo_count) if dev is not None else 0
        last = max([count, *(n for k, n in slots if k == kind)])
        views = []
        for n in range(1, last + 1):
            slot = slots.get((kind, n))
            views.append(_pdo_view(node, slot, bus.canopen.sync_period_ns) if slot is not None else PdoView(n, False))
        pdos[kind] = tuple(views)
    builtin = dev.source.removeprefix("builtin:") if dev is not None and dev.source.startswith("builtin:") else None
    return SlaveView(
        name=node.name,
        note=_note(device=builtin),
        comments=tuple(comments),
        dcf=dcf,
        node_id=node.node_id,
        heartbeat=_ms(node.heartbeat_ns),
        rpdo=pdos["rpdo"],
        tpdo=pdos["tpdo"],
        heartbeat_multiplier=_heartbeat_multiplier(node),
        driver=_ros_driver(joint)[0],
        scaling=_ros_driver(joint)[1],
    )


DCFGEN_HEARTBEAT_MULTIPLIER = 3  # dcfgen's default: the master's consumer time = 3 x the slave's producer time


def _heartbeat_multiplier(node: Node) -> str | None:
    """The factor dcfgen turns the slave's heartbeat_producer into the master's consumer time with (it keeps the
    integer part of producer x factor, in ms): written when the spec's heartbeat_timeout is not the default, as the
    shortest decimal that gives back exactly that many ms."""
    producer, timeout = _ms(node.heartbeat_ns), _ms(node.heartbeat_timeout_ns)
    if not producer or timeout is None or timeout == DCFGEN_HEARTBEAT_MULTIPLIER * producer:
        return None
    factor = timeout / producer
    while int(producer * factor) < timeout:  # a float a hair below the quotient would lose a millisecond
        factor = math.nextafter(factor, math.inf)
    return repr(factor)


def _pdo_view(node: Node, m: Message, sync_ns: int) -> PdoView:
    p = m.pdo
    assert p is not None and node.node_id is not None
    default_id = cia301.default_pdo_cob_id(p.kind, p.number, node.node_id)
    value = m.id | (cia301.PDO_EXTENDED if m.extended else 0)
    cob = "auto" if m.id == default_id and not m.extended else f"0x{value:X}"
    dev = node.device
    tpdo = p.kind == "tpdo"
    # TPDOs: netcfg's DCF writes inhibit time and event timer (0 = off) wherever the device has them: say so here too,
    # or dcfgen would keep a vendor EDS's defaults
    inhibit = (p.inhibit_100us or 0) if tpdo and (dev is None or dev.tpdo_inhibit_time) else p.inhibit_100us
    timer = (p.event_timer_ms or 0) if tpdo and (dev is None or dev.tpdo_event_timer) else p.event_timer_ms
    timing = default_timing(p.kind, p.transmission, p.event_timer_ms, p.inhibit_100us, sync_ns)
    note: dict[str, object] = {}
    if m.name != safe_name(f"{node.name}_{p.kind}{p.number}", "pdo"):
        note["message"] = m.name
    if (m.kind, m.period_ns, m.interval_ns) != timing:
        note["type"] = m.kind
        note["period_ns"] = m.period_ns if m.kind == "periodic" else None
        note["min_interarrival_ns"] = m.interval_ns if m.kind == "sporadic" else None
    return PdoView(
        number=p.number,
        enabled=True,
        note=_note(**note),
        cob_id=cob,
        transmission=p.transmission,
        inhibit_time=inhibit,
        event_timer=timer,
        sync_start=p.sync_start,
        mapping=tuple(_map_view(node, k, e) for k, e in enumerate(p.entries)),
    )


def _map_view(node: Node, k: int, e: PdoEntry) -> MapView:
    """An entry; its signal name is noted when it is not the one resolve would give it (pad<k>, or the object's)."""
    if cia301.is_dummy(e.index, e.sub):
        default = f"pad{k}"
    else:
        obj = node.device.lookup(e.index, e.sub) if node.device is not None else None
        default = snake(obj.name) if obj is not None else ""
    return MapView(f"0x{e.index:04X}", e.sub, _note(name=e.name) if e.name != default else "")
