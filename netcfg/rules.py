"""What a layer adds to resolution. The resolver calls these hooks for each bus (and each message on it); the
defaults are what a bus without the feature does, usually refusing the feature's keys. A link's rules
(netcfg.links: bit rate, payload, identifiers) subclass this, and a protocol's rules subclass its link's; the bus's
protocol names its rules (`netcfg.protocols.Protocol.rules`).
"""

from __future__ import annotations

from pathlib import Path as FsPath
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, Protocol

from netcfg import model
from netcfg.model import MessageKind
from netcfg.spec import schema
from netcfg.spec.source import Path, SourceMap
from netcfg.spec.suggest import did_you_mean, nodes_on_bus

if TYPE_CHECKING:
    from netcfg.diagnostics import Collector
    from netcfg.spec.units import Duration


class Resolution(Protocol):
    """What the layers' hooks read and call of the resolution they take part in: the spec, the model built so far
    and the shared checks. netcfg.resolve.core.Resolver is one; the hooks name this type, not the resolver, so the
    layers below the resolver do not depend on it (not even by annotations)."""

    spec: schema.Spec
    smap: SourceMap
    d: Collector
    spec_dir: FsPath
    model: model.Model
    spec_nodes: dict[str, schema.Node]
    spec_buses: dict[str, schema.Bus]
    slowest: dict[Path, int]  # period_range's slowest period, by the message's or trigger's path
    shared_node_ids: set[str]  # nodes whose node id another node on one of their buses has too
    actuator_replies: dict[str, str]  # an actuator's reply message -> the task that sends it

    def err(self, code: str, message: str, path: Path) -> None: ...

    def warn(self, code: str, message: str, path: Path) -> None: ...

    def key_or_item(self, path: Path, key: str) -> Path: ...

    def ns(self, value: Duration | None, path: Path, ec_ns: int | None) -> int | None: ...

    def check_offset(self, offset: int | None, period: int | None, path: Path, what: str = ...) -> None: ...

    def period_range(
        self, given: tuple[Duration, Duration], period: int | None, path: Path, ec: int | None
    ) -> int | None: ...

    def task_refs(self) -> list[str]: ...

    def masters(self, bus: str) -> list[str]: ...

    def claim_implicit_name(self, name: str, what: str) -> None: ...


Rate = tuple[MessageKind | None, int | None, int | None]  # a message's (kind, period, min. interarrival) in ns


class Release(NamedTuple):
    """A message's release as the spec gives it, in ns: what a protocol's release grid checks."""

    kind: MessageKind
    period: int | None
    offset: int | None
    offset_auto: bool  # 'offset: auto': derived from flows in a last pass


class BusRules:
    name = ""
    section: str | None = None  # the bus's own section in the spec ('ftt:', 'canopen:', 'ethernet:')
    explicit_ids = True  # a message needs an 'id' unless the protocol derives one
    id_meaning = "a CAN id"  # what the id is, for the message asking for it
    extended_ids = True  # whether 'extended' means anything on this bus
    rate_adaptation = False  # 'period_range' (FTT-CAN on-line rate adaptation)
    auto_offsets = False  # 'offset: auto' (derived from flows)
    device_nodes = False  # its nodes are devices of the protocol: node ids 1..127, device profiles, heartbeats
    pdo_messages = False  # every message on it names a PDO (EtherCAT: a slave's); one without is refused at once

    def __init__(self, r: Resolution) -> None:
        self.r = r

    # -- buses
    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        """Check the bus's own settings and fill its protocol section in the model."""

    def required_section(self, b: schema.Bus, title: str, example: str, path: Path) -> Any:
        """The bus's own section (self.section) where the protocol cannot do without it, or None and the error
        naming what to write (`example`)."""
        assert self.section is not None
        found = getattr(b, self.section)
        if found is None:
            self.r.err("missing-section", f"{title} bus '{b.name}' needs '{self.section}: {example}'", path)
        return found

    def resolve_items(self) -> None:
        """What the protocol adds once every message is resolved (implicit messages, triggers, topology)."""

    def section_master(
        self, b: schema.Bus, given: str | None, path: Path, key: str, role: str, title: str, code: str
    ) -> str | None:
        """The node that drives the protocol on bus b: the one its section (at `path`) names (`given`, at `key`),
        which must be on the bus, else the bus's one node with 'role: master'; None when there is none (reported).
        `role`: what the node is ("SYNC producer"), `title`: the protocol's ("CANopen"), `code`: the error without
        a master."""
        if given is None:
            ms = self.r.masters(b.name)
            if len(ms) != 1:
                self.r.err(
                    code,
                    f"{title} bus '{b.name}' needs one node with 'role: master' (found "
                    f"{len(ms)}) or '{self.section}: {{{key}: <node>}}'",
                    path,
                )
                return None
            return ms[0]
        if given not in self.r.spec_nodes or b.name not in self.r.spec_nodes[given].buses:
            hint = did_you_mean(given, nodes_on_bus(self.r.spec, b.name))
            self.r.err("unknown-node", f"{role} '{given}' is not a node on bus '{b.name}'{hint}", (*path, key))
            return None
        return given

    def cycle_ns(self, b: schema.Bus) -> int | None:
        """The length the spec gives the protocol's cycle, in which the bus's times may be counted ('2 ec': FTT-CAN's
        elementary cycle); None: the protocol has none, or the spec gives it no length in time units."""
        return None

    def check_identifiers(self, bus: model.Bus) -> None:
        """Identifiers on the bus are unique and none is reserved by the protocol."""

    # -- messages
    def carries_messages(self, bus: model.Bus) -> bool:
        """False when the bus's own section failed (reported already): its messages cannot be resolved."""
        return True

    def resolve_pdo(
        self, m: schema.Message, sbus: schema.Bus, bus: model.Bus, path: Path
    ) -> tuple[model.Pdo, tuple[model.Signal, ...]] | None:
        self.r.err("wrong-section", f"PDOs exist on CANopen buses; '{sbus.name}' is {self.name}", (*path, "pdo"))
        return None

    def link_rules(self, bus: model.Bus) -> BusRules:
        """The rules that judge a message's frame on `bus` (its payload, CAN FD format): the protocol's own, or its
        link's where the protocol runs over more than one (netcfg.links.canfd.OverCanLinks)."""
        return self

    def check_payload(self, m: schema.Message, size: int, path: Path) -> None:
        """The payload fits one frame of the protocol."""

    def pdo_timing(self, pdo: model.Pdo, bus: model.Bus, rate: Rate, path: Path, jitter: int = 0) -> Rate | None:
        """-> the message's rate after the PDO's own timing settings (`jitter`: the spec's release jitter of the
        message); None when they leave the rate unbounded (reported here)."""
        return rate

    def release_offset(self, m: schema.Message, release: Release, path: Path, ec: int | None) -> int | None:
        """-> the message's release offset once the protocol's release grid is checked."""
        return release.offset

    def resolve_window(
        self, m: schema.Message, sbus: schema.Bus, kind: MessageKind, path: Path
    ) -> tuple[Literal["sync", "async"] | None, int | None]:
        """-> (FTT-CAN window, FTT id); other protocols refuse both keys."""
        for key in ("window", "ftt_id"):
            if getattr(m, key) is not None:
                self.r.err(
                    "wrong-section", f"'{key}' is an FTT-CAN setting; bus '{sbus.name}' is {self.name}", (*path, key)
                )
        return None, None

    def message_id(self, m: schema.Message, pdo: model.Pdo | None, path: Path) -> int | None:
        """-> the message's identifier: the spec's, or the one the protocol gives it by default."""
        return m.id

    def id_limit(self, extended: bool) -> tuple[int, str]:
        """-> (largest identifier, its width in words)."""
        return (0x1FFFFFFF, "29 bits") if extended else (0x7FF, "11 bits")

    def frame_format(self, m: schema.Message, path: Path) -> tuple[bool, bool]:
        """-> (CAN FD frame, bit-rate switch); only CAN FD buses have either."""
        for key in ("fd", "brs"):
            if getattr(m, key) is not None:
                self.r.err("wrong-section", f"'{key}' is a CAN FD setting; this bus is {self.name}", (*path, key))
        return False, False

    def check_fields(self, m: schema.Message, path: Path) -> None:
        """Message keys that belong to another protocol."""
        if m.udp is not None:
            self.r.err("wrong-section", "'udp' belongs to ethernet-udp buses", (*path, "udp"))
