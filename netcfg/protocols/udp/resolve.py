"""Switched Ethernet with UDP (seed 001): the switches and their cabling (a tree), one-byte application message
ids unique per sender, and payloads that fit one unfragmented datagram."""

from __future__ import annotations

from netcfg import model
from netcfg.rules import BusRules
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean
from netcfg.timing.ethernet import QUEUE_FRAMES
from netcfg.timing.frames import APP_ID_BYTES, MAX_UDP_PAYLOAD


def _queue_path(bus: Path, j: int, k: int, port: schema.SwitchPort, switch: schema.Switch) -> Path:
    """Where a port's queue depth is written: its own `queue`, its switch's, or (the default) the port."""
    sw = (*bus, "ethernet", "switches", j)
    if port.queue is None and switch.queue is not None:
        return (*sw, "queue")
    return (*sw, "ports", k, "queue")


class UdpRules(BusRules):
    name = "ethernet-udp"
    section = "ethernet"
    id_meaning = "the application message id (Table 6.1 style, 0..255)"
    extended_ids = False

    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        if b.ethernet:
            bus.switches = [
                model.Switch(
                    s.name,
                    {p.port: p.to for p in s.ports},
                    {p.port: p.cable for p in s.ports},
                    s.latency.ns or 0,
                    {p.port: p.queue or s.queue or QUEUE_FRAMES for p in s.ports},
                    {p.port: _queue_path(path, j, k, p, s) for k, p in enumerate(s.ports)},
                    s.queue or QUEUE_FRAMES,
                    (*path, "ethernet", "switches", j),
                )
                for j, s in enumerate(b.ethernet.switches)
            ]

    def resolve_items(self) -> None:
        self.resolve_topologies()
        self.resolve_nic_queues()

    def resolve_nic_queues(self) -> None:
        """A node's nic_queue is its NIC's on every Ethernet bus it is on; elsewhere it means nothing."""
        ethernet = {b.name for b in self.r.model.buses.values() if b.protocol == self.name}
        for i, n in enumerate(self.r.spec.nodes):
            if n.nic_queue is None or n.name not in self.r.model.nodes:
                continue
            if ethernet.intersection(n.buses):
                self.r.model.nodes[n.name].nic_queue = n.nic_queue
            else:
                self.r.warn(
                    "wrong-section",
                    f"node '{n.name}' is on no Ethernet bus: its nic_queue has no effect (CAN queues are tx_queue): "
                    "remove it",
                    ("nodes", i, "nic_queue"),
                )

    def check_payload(self, m: schema.Message, size: int, path: Path) -> None:
        if APP_ID_BYTES + size > MAX_UDP_PAYLOAD:
            self.r.err(
                "payload",
                f"{size} bytes plus the 1-byte message id exceed one unfragmented UDP datagram "
                f"({MAX_UDP_PAYLOAD} bytes)",
                (*path, "size"),
            )

    def id_limit(self, extended: bool) -> tuple[int, str]:
        return 0xFF, "one byte"

    def check_fields(self, m: schema.Message, path: Path) -> None:
        if m.extended is not None:
            self.r.err("wrong-section", "'extended' is a CAN setting", (*path, "extended"))
        if "may_be_lost" in m.model_fields_set:
            self.r.err(
                "wrong-section",
                "'may_be_lost' is a CAN setting (a FIFO transmit queue that drops)",
                (*path, "may_be_lost"),
            )

    def check_identifiers(self, bus: model.Bus) -> None:
        seen: dict[tuple[str, int], str] = {}
        for m in bus.messages:
            if m.id < 0:
                continue
            key = (m.producer, m.id)
            if key in seen:
                self.r.err(
                    "duplicate-id",
                    f"'{m.producer}' already sends message id 0x{m.id:02X} as '{seen[key]}'",
                    (*m.path, "id"),
                )
            seen[key] = m.name

    # -- topology ----------------------------------------------------------------------------------------------
    def resolve_topologies(self) -> None:
        """Every node of an Ethernet bus hangs on one switch port, and the cables form a tree (no spanning tree
        protocol is assumed, so a loop, parallel cables included, would flood the network)."""
        for bus in self.r.model.buses.values():
            if bus.protocol != "ethernet-udp":
                continue
            import networkx as nx  # only Ethernet buses need it; keeps start-up fast for CAN specs

            graph: nx.Graph = nx.Graph()
            switch_names = {s.name for s in bus.switches}
            attached: dict[str, str] = {}
            sbus = self.r.spec_buses[bus.name]
            assert sbus.ethernet is not None or not bus.switches
            for j, sw in enumerate(sbus.ethernet.switches if sbus.ethernet else []):
                spath = (*bus.path, "ethernet", "switches", j)
                graph.add_node(sw.name)
                ports: set[int] = set()
                for k, p in enumerate(sw.ports):
                    ppath = (*spath, "ports", k)
                    if p.port in ports:
                        self.r.err("topology", f"switch '{sw.name}' lists port {p.port} twice", (*ppath, "port"))
                        continue
                    ports.add(p.port)
                    where = f"{sw.name} port {p.port}"
                    if p.to not in switch_names and p.to not in bus.nodes:
                        self.r.err(
                            "unknown-node",
                            f"{where} leads to '{p.to}', which is neither a switch nor a node on bus '{bus.name}'"
                            f"{did_you_mean(p.to, [*switch_names, *bus.nodes])}",
                            (*ppath, "to"),
                        )
                        continue
                    if p.to == sw.name:
                        self.r.err("topology", f"{where} is cabled to its own switch", (*ppath, "to"))
                        continue
                    if p.to not in switch_names and p.to in attached:
                        self.r.err(
                            "topology", f"node '{p.to}' is cabled twice ({attached[p.to]} and {where})", (*ppath, "to")
                        )
                        continue
                    if p.to in graph and nx.has_path(graph, sw.name, p.to):
                        loop = " - ".join(nx.shortest_path(graph, p.to, sw.name))
                        self.r.err(
                            "topology",
                            f"the cable from {where} to '{p.to}' closes a loop ({loop} - {p.to}); "
                            "switched Ethernet without a spanning tree needs a tree: remove one cable",
                            (*ppath, "to"),
                        )
                        continue
                    attached[p.to] = where
                    graph.add_edge(sw.name, p.to)
            if not bus.switches:
                if len(bus.nodes) == 2:
                    graph.add_edge(*bus.nodes)
                elif len(bus.nodes) > 2:
                    self.r.err(
                        "topology",
                        f"bus '{bus.name}' has {len(bus.nodes)} nodes but no switch; add 'ethernet: "
                        "{switches: [...]}' saying which node hangs on which port",
                        bus.path,
                    )
                    continue
            for n in bus.nodes:
                if bus.switches and n not in graph:
                    self.r.err(
                        "topology", f"node '{n}' is on bus '{bus.name}' but on no switch port; cable it", bus.path
                    )
            if graph.number_of_nodes() and not nx.is_connected(graph):
                parts = " / ".join(", ".join(sorted(c)) for c in nx.connected_components(graph))
                self.r.err(
                    "topology",
                    f"the cabling of bus '{bus.name}' falls apart into {parts}; connect the switches",
                    (*bus.path, "ethernet"),
                )
