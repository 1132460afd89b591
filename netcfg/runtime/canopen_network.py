"""Which bus a CANopen master runs and who its slaves are, as runtime.json says; shared by the set-up and the cycle."""

from __future__ import annotations

from netcfg.runtime import Bus, Node, RuntimeConfig

__all__ = ["canopen_bus", "canopen_slaves", "master_node"]


def canopen_bus(cfg: RuntimeConfig, bus_name: str | None) -> Bus:
    """The CANopen bus named, or the config's only one; ValueError for a bus of another protocol, or when there is
    no single CANopen bus to default to."""
    if bus_name is not None:
        bus = cfg.bus(bus_name)
        if bus.canopen is None:
            raise ValueError(f"bus '{bus_name}' is a {bus.protocol} bus, not CANopen")
        return bus
    buses = [b for b in cfg.buses if b.canopen is not None]
    if len(buses) != 1:
        names = ", ".join(b.name for b in buses) or "none"
        raise ValueError(f"{cfg.system} has {len(buses)} CANopen buses ({names}); say which one with bus_name")
    return buses[0]


def canopen_slaves(cfg: RuntimeConfig, bus: Bus) -> list[Node]:
    """The slaves a master configures and collects from: every node on the bus with a node id but the masters."""
    return [n for n in (cfg.node(name) for name in bus.nodes) if n.role != "master" and n.node_id is not None]


def master_node(cfg: RuntimeConfig, bus: Bus) -> Node:
    assert bus.canopen is not None
    masters = [n for n in (cfg.node(name) for name in bus.nodes) if n.role == "master"]
    producer = [n for n in masters if n.name == bus.canopen.sync_producer]
    if producer or masters:
        return (producer or masters)[0]
    raise ValueError(f"bus '{bus.name}' has no master node")
