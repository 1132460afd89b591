"""An EtherCAT segment's resolution: its `ethercat:` section (cycle, master, slaves in wire order, distributed
clocks), each slave's device from its ESI file or a built-in CoE profile, and the checks of its PDO assignment
(0x1C12/0x1C13) against the ESI's rules (the PDOs it has, Fixed, Mandatory, Exclude, the sync manager each belongs
to), of every mapped entry against the object dictionary (present, mappable in that direction, its length), and of
the process image it makes. The cycle's timing is the analysis' (analysis.py)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from netcfg import model
from netcfg.devices import DeviceProfile, builtin_profile, builtin_profile_names
from netcfg.inputs import check_input_path
from netcfg.links import ethercat as link
from netcfg.protocols.ethercat.messages import object_ref
from netcfg.rules import BusRules, Rate
from netcfg.spec import schema
from netcfg.spec.source import Path
from netcfg.spec.suggest import did_you_mean

if TYPE_CHECKING:  # imported where used: a spec without an EtherCAT segment does not pay for them (nor for XML)
    from netcfg.protocols.ethercat import esi as esi_file
    from netcfg.protocols.ethercat.segment import Segment, Slave

DC_SYNC0 = 0x0300  # register 0x0980: cyclic unit and SYNC0 active (ETG.1020), what CiA 402 drives' ESIs give
# the sync managers of a CoE slave without an ESI (ETG.2000's usual layout: two mailboxes, outputs, inputs)
PROFILE_SMS = (
    ("MBoxOut", 0x1000, 128, 0x26),
    ("MBoxIn", 0x1080, 128, 0x22),
    ("Outputs", 0x1100, 0, 0x64),
    ("Inputs", 0x1180, 0, 0x20),
)
SM_KIND = {"rx": "Outputs", "tx": "Inputs"}
SIDE = {"rx": "RxPDO (outputs, 0x1C12)", "tx": "TxPDO (inputs, 0x1C13)"}


class EthercatRules(BusRules):
    name = "ethercat"
    section = "ethercat"
    id_meaning = "none: EtherCAT process data comes from the slaves' PDOs"
    pdo_messages = True
    extended_ids = False

    def carries_messages(self, bus: model.Bus) -> bool:
        return True

    def check_fields(self, m: schema.Message, path: Path) -> None:
        if m.pdo is None:
            self.r.err(
                "wrong-section",
                f"message '{m.name}': an EtherCAT bus carries the slaves' PDOs, not messages of its own: name one "
                "of a slave's assigned PDOs with 'pdo: {tpdo: N}' (its inputs, 0x1A00 + N - 1) or 'pdo: {rpdo: N}' "
                "(its outputs, 0x1600 + N - 1)",
                path,
            )
            return
        for key in ("id", "offset", "jitter", "udp"):
            if getattr(m, key) is not None:
                self.r.err(
                    "wrong-section",
                    f"message '{m.name}': '{key}' means nothing for a PDO in an EtherCAT cycle (its place in the "
                    "process image is its address, the cycle its release)",
                    (*path, key),
                )

    def resolve_pdo(
        self, m: schema.Message, sbus: schema.Bus, bus: model.Bus, path: Path
    ) -> tuple[model.Pdo, tuple[model.Signal, ...]] | None:
        from netcfg.protocols.ethercat.messages import resolve_pdo

        return resolve_pdo(self.r, m, sbus, bus, path)

    def pdo_timing(self, pdo: model.Pdo, bus: model.Bus, rate: Rate, path: Path, jitter: int = 0) -> Rate | None:
        """A PDO rides every cycle: periodic at the bus's cycle (a period, if given, must be it)."""
        kind, period, mit = rate
        seg = bus.ethercat
        if seg is None:
            return None
        if (kind is not None and kind != "periodic") or (period is not None and period != seg.cycle_ns):
            self.r.err(
                "period",
                f"a PDO of EtherCAT bus '{bus.name}' rides every cycle ({seg.cycle_ns / 1000:g} us): drop 'period' "
                "and 'type'",
                path,
            )
            return None
        return "periodic", seg.cycle_ns, mit

    def message_id(self, m: schema.Message, pdo: model.Pdo | None, path: Path) -> int | None:
        from netcfg.protocols.ethercat.messages import message_id

        if pdo is None:
            return None
        segs = [b.ethercat for b in self.r.model.buses.values() if b.ethercat is not None]
        return next((x for seg in segs if (x := message_id(seg, pdo)) is not None), None)

    def resolve_bus(self, b: schema.Bus, bus: model.Bus, path: Path) -> None:
        if bus.bitrate not in link.BIT_RATES:
            self.r.err(
                "bitrate", f"EtherCAT runs at 100 Mbit/s (or 1 Gbit/s), not {bus.bitrate:,} bit/s", (*path, "bitrate")
            )
        sec: schema.EthercatParams | None = self.required_section(b, "EtherCAT", "{cycle: ..., slaves: [...]}", path)
        epath = (*path, "ethercat")
        if sec is None:
            return
        cycle = sec.cycle.to_ns(None) or 0
        if cycle <= 0:
            self.r.err("ethercat", "the cycle must be longer than 0", (*epath, "cycle"))
            return
        master = sec.master or next(
            (n.name for n in self.r.spec.nodes if b.name in n.buses and n.role == "master"), None
        )
        if master is None:
            self.r.err(
                "ethercat", f"bus '{b.name}' has no master: give a node 'role: master' or 'ethercat.master'", epath
            )
        elif master not in bus.nodes:
            self.r.err(
                "unknown-node",
                f"the master '{master}' is not on bus '{b.name}'{did_you_mean(master, bus.nodes)}",
                (*epath, "master"),
            )
        sync0 = sec.sync0_cycle.to_ns(None) if sec.sync0_cycle else cycle
        if sync0 is None or sync0 <= 0 or (cycle % sync0 and sync0 % cycle):
            self.r.err(
                "dc",
                f"the SYNC0 cycle must divide the bus cycle ({cycle / 1000:g} us) or be a multiple of it",
                (*epath, "sync0_cycle"),
            )
            sync0 = cycle
        shift = sec.sync0_shift.to_ns(None) if sec.sync0_shift else cycle // 2
        if shift is None or not 0 <= shift < sync0:
            self.r.err("dc", "the SYNC0 shift must lie inside the SYNC0 cycle", (*epath, "sync0_shift"))
            shift = cycle // 2
        from netcfg.protocols.ethercat.segment import Segment

        seg = Segment(cycle, master, [], sync0, shift, sec.master_jitter.to_ns(None) or 0, epath)
        seen: dict[str, int] = {}
        for i, s in enumerate(sec.slaves):
            spath = (*epath, "slaves", i)
            if s.position != i:
                self.r.err(
                    "ethercat",
                    f"slave '{s.node}' is at position {s.position} but listed as number {i}: list "
                    "the slaves in wire order from position 0",
                    (*spath, "position"),
                )
            if s.node in seen:
                self.r.err("ethercat", f"node '{s.node}' is slave {seen[s.node]} already", (*spath, "node"))
                continue
            seen[s.node] = i
            if s.node not in bus.nodes:
                self.r.err(
                    "unknown-node",
                    f"slave '{s.node}' is not a node on bus '{b.name}'{did_you_mean(s.node, bus.nodes)}",
                    (*spath, "node"),
                )
                continue
            if s.node == master:
                self.r.err("ethercat", f"'{s.node}' is the bus's master; a master is no slave", (*spath, "node"))
                continue
            slave = self.resolve_slave(s, spath)
            if slave is not None:
                own = slave.sync0_shift_ns
                if s.sync0_shift is not None and own is not None and not 0 <= own < sync0:
                    self.r.err(
                        "dc",
                        f"slave '{s.node}': its SYNC0 shift must lie inside the SYNC0 cycle ({sync0 / 1000:g} us)",
                        (*spath, "sync0_shift"),
                    )
                    slave.sync0_shift_ns = shift
                seg.slaves.append(slave)
        for n in bus.nodes:
            if n != master and n not in seen:
                self.r.err(
                    "ethercat",
                    f"node '{n}' is on EtherCAT bus '{b.name}' but is none of its slaves: add it to "
                    "ethercat.slaves at its place in the line",
                    epath,
                )
        seg.lay_out()
        self.check_image(seg)
        bus.ethercat = seg

    # -- a slave -----------------------------------------------------------------------------------------------
    def resolve_slave(self, s: schema.EthercatSlave, spath: Path) -> Slave | None:
        if (s.esi is None) == (s.profile is None):
            self.r.err(
                "ethercat", f"slave '{s.node}' needs its device: 'esi: {{file: ...}}' or 'profile: cia402'", spath
            )
            return None
        from netcfg.protocols.ethercat.segment import Slave

        forwarding = s.forwarding_delay.to_ns(None) if s.forwarding_delay else link.default_forwarding_ns(None)
        slave = Slave(
            s.node,
            s.position,
            s.cable,
            forwarding or 0,
            0,
            0,
            0,
            "",
            "",
            spath,
            sync0_shift_ns=s.sync0_shift.to_ns(None) if s.sync0_shift else None,
            min_cycle_ns=s.min_cycle.to_ns(None) if s.min_cycle else None,
        )
        if s.esi is not None:
            return self.from_esi(s, s.esi, slave, spath)
        assert s.profile is not None
        if s.profile not in builtin_profile_names():
            self.r.err(
                "unknown-device",
                f"no built-in profile '{s.profile}'{did_you_mean(s.profile, builtin_profile_names())}",
                (*spath, "profile"),
            )
            return None
        return self.from_profile(s, builtin_profile(s.profile), slave, spath)

    def from_esi(self, s: schema.EthercatSlave, e: schema.EthercatEsi, slave: Slave, spath: Path) -> Slave | None:
        from netcfg.protocols.ethercat import esi as esi_file
        from netcfg.protocols.ethercat.segment import AssignedPdo, SyncManagerSetup

        try:
            file = check_input_path(self.r.spec_dir, e.file, "ESI file")
            dev = esi_file.select(esi_file.read_esi(file), e.device, e.file)
        except (ValueError, esi_file.EsiError) as exc:
            self.r.err("esi", str(exc), (*spath, "esi"))
            return None
        slave.vendor_id, slave.product_code, slave.revision = dev.vendor_id, dev.product_code, dev.revision
        if s.forwarding_delay is None:
            slave.forwarding_ns = link.default_forwarding_ns(dev.physics)
            unknown = link.unknown_physics(dev.physics)
            if unknown:
                known = ", ".join(f"{k} {v}" for k, v in link.PHYSICS.items())
                self.r.warn(
                    "esi-physics",
                    f"slave '{s.node}': {dev.type_name} ({e.file}:{dev.line}) has ports of physics "
                    f"{', '.join(repr(x) for x in unknown)} in Physics=\"{dev.physics}\", which netcfg does not know "
                    f"({known}): its forwarding delay is taken as an RJ45 slave's "
                    f"{link.MII_FORWARDING_NS / 1000:g} us; set forwarding_delay to say otherwise",
                    (*spath, "esi"),
                )
        slave.device, slave.source = dev.type_name, e.file
        assign = dev.objects.get((0x1C12, 1))
        slave.assign_writable = dev.pdo_assign or (assign is not None and "w" in assign.access)
        where = f"{e.file}:{dev.line}"
        mappings = self.mappings(s, spath, lambda index: dev.pdo(index) is not None, where)
        for side, given, pdos in (("rx", s.rxpdo, dev.rx_pdos), ("tx", s.txpdo, dev.tx_pdos)):
            key = f"{side}pdo"
            mandatory = [p.index for p in pdos if p.mandatory]
            chosen = given if given is not None else (mandatory or [p.index for p in pdos[:1]])
            assigned: list[int] = []
            for k, index in enumerate(chosen):
                at = (*spath, key, k) if given is not None else spath
                pdo = dev.pdo(index)
                if pdo is None:
                    names = [f"0x{p.index:04X}" for p in pdos]
                    self.r.err(
                        "pdo-assignment",
                        f"slave '{s.node}': {dev.type_name} ({where}) has no PDO 0x{index:04X}; "
                        f"its {SIDE[side]}s are {', '.join(names) or 'none'}",
                        at,
                    )
                    continue
                if pdo.direction != side:
                    self.r.err(
                        "pdo-assignment",
                        f"slave '{s.node}': 0x{index:04X} is a {SIDE[pdo.direction]}, not a "
                        f"{SIDE[side]}; assign it under '{pdo.direction}pdo'",
                        at,
                    )
                    continue
                if index in assigned:
                    self.r.err("pdo-assignment", f"slave '{s.node}': PDO 0x{index:04X} is assigned twice", at)
                    continue
                excluded = {x for x in assigned if index in getattr(dev.pdo(x), "excludes", ())}
                clash = next(
                    (x for x in assigned if x in pdo.excludes or x in excluded),
                    None,
                )
                if clash is not None:
                    self.r.err(
                        "pdo-assignment",
                        f"slave '{s.node}': PDO 0x{index:04X} and 0x{clash:04X} exclude each "
                        f"other ({e.file}:{pdo.line}: <Exclude>); assign one of them",
                        at,
                    )
                    continue
                sm = dev.sync_managers[pdo.sm] if pdo.sm is not None and pdo.sm < len(dev.sync_managers) else None
                if sm is None or sm.kind != SM_KIND[side]:
                    self.r.err(
                        "pdo-assignment",
                        f"slave '{s.node}': PDO 0x{index:04X} belongs to sync manager "
                        f"{pdo.sm} ({sm.kind if sm else 'none'}, {e.file}:{pdo.line}), not to the {SM_KIND[side]} "
                        "one",
                        at,
                    )
                    continue
                entries = tuple((x.index, x.sub, x.bits, x.name, x.data_type) for x in pdo.entries)
                if index in mappings:
                    if pdo.fixed:
                        self.r.err(
                            "pdo-mapping",
                            f"slave '{s.node}': PDO 0x{index:04X} is Fixed in {e.file}:{pdo.line}; "
                            "its mapping cannot be changed: remove it from 'pdos'",
                            mappings[index][1],
                        )
                        continue
                    entries = self.mapped_esi(s.node, dev, side, mappings[index], e.file)
                    slave.pdo_mappings[index] = tuple((x[0], x[1], x[2]) for x in entries)
                else:
                    for x in pdo.entries:
                        od = dev.objects.get((x.index, x.sub))
                        if not x.padding and od is not None and od.bits and od.bits != x.bits:
                            self.r.err(
                                "pdo-mapping",
                                f"slave '{s.node}': {e.file}:{x.line}: PDO 0x{index:04X} maps "
                                f"0x{x.index:04X}:{x.sub} with {x.bits} bits, but the dictionary gives it "
                                f"{od.bits}",
                                at,
                            )
                    if not pdo.entries:
                        self.r.warn(
                            "pdo-mapping",
                            f"slave '{s.node}': PDO 0x{index:04X} maps nothing in "
                            f"{e.file}:{pdo.line}; give its mapping in 'pdos'",
                            at,
                        )
                assigned.append(index)
                (slave.rx if side == "rx" else slave.tx).append(AssignedPdo(index, side, pdo.sm or 0, entries))
            for index in mandatory:
                if index not in assigned and given is not None:
                    self.r.err(
                        "pdo-assignment",
                        f"slave '{s.node}': PDO 0x{index:04X} is Mandatory in {e.file}; assign it in '{key}'",
                        (*spath, key),
                    )
        for n, sm in enumerate(dev.sync_managers):
            length = {"Outputs": slave.out_bytes, "Inputs": slave.in_bytes}.get(sm.kind, sm.default_size or 0)
            slave.sync_managers.append(SyncManagerSetup(n, sm.kind, sm.start, length, sm.control))
        mode = None
        if s.opmode is not None:
            mode = next((m for m in dev.op_modes if m.name == s.opmode), None)
            if mode is None:
                self.r.err(
                    "dc",
                    f"slave '{s.node}': {dev.type_name} has no DC op mode '{s.opmode}'"
                    f"{did_you_mean(s.opmode, [m.name for m in dev.op_modes])}",
                    (*spath, "opmode"),
                )
        elif dev.op_modes:
            mode = dev.op_modes[0]
        slave.assign_activate = (
            s.assign_activate if s.assign_activate is not None else (mode.assign_activate if mode else 0)
        )
        if mode is not None and slave.sync0_shift_ns is None and mode.shift_time_sync0:
            slave.sync0_shift_ns = mode.shift_time_sync0
        return slave

    def mapped_esi(
        self, node: str, dev: esi_file.EsiDevice, side: str, mapping: tuple[list[tuple[int, int]], Path], file: str
    ) -> tuple[tuple[int, int, int, str, str], ...]:
        out = []
        letter = "R" if side == "rx" else "T"
        for k, (index, sub) in enumerate(mapping[0]):
            at = (*mapping[1][:-1], "map", k)
            od = dev.objects.get((index, sub))
            if od is None:
                self.r.err("pdo-mapping", f"slave '{node}': {file} has no object 0x{index:04X}:{sub}", at)
                continue
            if letter not in od.pdo_mapping:
                self.r.err(
                    "pdo-mapping",
                    f"slave '{node}': 0x{index:04X}:{sub} ({od.name}) is not mappable to a "
                    f"{SIDE[side]} ({file}: PdoMapping '{od.pdo_mapping or 'none'}')",
                    at,
                )
                continue
            out.append((index, sub, od.bits, od.name, ""))
        return tuple(out)

    def mappings(
        self, s: schema.EthercatSlave, spath: Path, known: object, where: str
    ) -> dict[int, tuple[list[tuple[int, int]], Path]]:
        """The spec's `pdos:` by mapping index: the objects it maps and where the entry is written."""
        out: dict[int, tuple[list[tuple[int, int]], Path]] = {}
        for k, p in enumerate(s.pdos):
            ppath = (*spath, "pdos", k, "index")
            refs = []
            for j, ref in enumerate(p.map):
                parsed = object_ref(ref)
                if parsed is None:
                    self.r.err(
                        "pdo-mapping",
                        f"'{ref}' is no object: write 0x6064 or '0x30D1:2'",
                        (*spath, "pdos", k, "map", j),
                    )
                    continue
                refs.append(parsed)
            if p.index in out:
                self.r.err("pdo-mapping", f"slave '{s.node}': PDO 0x{p.index:04X} is mapped twice", ppath)
            out[p.index] = (refs, ppath)
        return out

    def from_profile(self, s: schema.EthercatSlave, prof: DeviceProfile, slave: Slave, spath: Path) -> Slave:
        from netcfg.protocols.ethercat.segment import AssignedPdo, SyncManagerSetup

        slave.vendor_id, slave.product_code = prof.vendor_id or 0, prof.product_code or 0
        slave.revision, slave.device, slave.source = prof.revision or 0, prof.name, prof.source
        mappings = self.mappings(s, spath, None, prof.source)
        for side, given in (("rx", s.rxpdo), ("tx", s.txpdo)):
            key = f"{side}pdo"
            lo = 0x1600 if side == "rx" else 0x1A00
            ours = [i for i in mappings if lo <= i < lo + 0x200]
            for k, index in enumerate(given if given is not None else ours):
                at = (*spath, key, k) if given is not None else spath
                if index not in mappings:
                    self.r.err(
                        "pdo-assignment",
                        f"slave '{s.node}': PDO 0x{index:04X} has no mapping: a profile "
                        "drive's PDOs are the ones 'pdos' maps",
                        at,
                    )
                    continue
                if not lo <= index < lo + 0x200:
                    self.r.err(
                        "pdo-assignment",
                        f"slave '{s.node}': 0x{index:04X} is no {SIDE[side]} (0x{lo:04X}..0x{lo + 0x1FF:04X})",
                        at,
                    )
                    continue
                refs, ppath = mappings[index]
                entries = []
                for j, (oi, sub) in enumerate(refs):
                    mpath = (*ppath[:-1], "map", j)
                    obj = prof.lookup(oi, sub)
                    if obj is None:
                        self.r.err(
                            "pdo-mapping",
                            f"slave '{s.node}': the {prof.name} profile has no object 0x{oi:04X}:{sub}",
                            mpath,
                        )
                        continue
                    ok = obj.pdo_mappable and (obj.writable if side == "rx" else obj.readable)
                    if not ok:
                        why = (
                            "is not PDO-mappable"
                            if not obj.pdo_mappable
                            else (
                                f"is {obj.access}: an RxPDO writes it"
                                if side == "rx"
                                else f"is {obj.access}: unreadable"
                            )
                        )
                        self.r.err("pdo-mapping", f"slave '{s.node}': 0x{oi:04X}:{sub} ({obj.name}) {why}", mpath)
                        continue
                    entries.append((oi, sub, obj.bits, obj.name, obj.type_name))
                slave.pdo_mappings[index] = tuple((e[0], e[1], e[2]) for e in entries)
                (slave.rx if side == "rx" else slave.tx).append(
                    AssignedPdo(index, side, 2 if side == "rx" else 3, tuple(entries))
                )
        for n, (kind, start, size, control) in enumerate(PROFILE_SMS):
            length = {"Outputs": slave.out_bytes, "Inputs": slave.in_bytes}.get(kind, size)
            slave.sync_managers.append(SyncManagerSetup(n, kind, start, length, control))
        slave.assign_activate = s.assign_activate if s.assign_activate is not None else DC_SYNC0
        return slave

    # -- the image ---------------------------------------------------------------------------------------------
    def check_image(self, seg: Segment) -> None:
        """Every entry of 8 bits or more starts on a byte, so that the master (and a C struct) can address it."""
        for e in (*seg.outputs, *seg.inputs):
            if not e.padding and e.bits >= 8 and e.bit_offset % 8:
                slave = next(s for s in seg.slaves if s.node == e.slave)
                self.r.err(
                    "process-image",
                    f"slave '{e.slave}': 0x{e.index:04X}:{e.sub} ({e.bits} bits, PDO "
                    f"0x{e.pdo:04X}) starts at bit {e.bit_offset % 8} of a byte; pad the bits before it to a "
                    "whole byte",
                    slave.path,
                )
