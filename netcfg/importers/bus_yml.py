"""Import a Lely dcfgen / ros2_canopen bus.yml into a netcfg spec.

The two dialects (Lely's dcfgen README, ros2_canopen's "Bus Configuration File" page):
- Lely: top-level `options`, `master` and one mapping per slave keyed by its name (keys starting with '.' are
  ignored, as dcfgen does: they hold YAML anchors).
- ros2_canopen: `options`, `master`, `defaults` and `nodes` (a mapping, or a list of one-key mappings as the
  documentation shows it). `defaults` is merged into every node key by key (a node's `tpdo:` replaces the defaults'
  `tpdo:` as a whole) and the node's value wins. ros2_canopen's own preprocessor (lely_core_libraries/cogen) lets
  the defaults win instead, so a node overriding a default gets a warning: check which value the robot runs with.

Mapping (spec <- bus.yml):
- system: the `# netcfg:` header written by our bus.yml emitter, else the file's stem, or its folder's name when
  the stem is the generic 'bus' (ros2_canopen's config/<name>/bus.yml), made a safe name. One CANopen bus
  (`can0` unless the header names it); bitrate from master.baudrate in kbit/s (Lely's default 1000; --bitrate wins);
  SYNC period and window from master.sync_period / sync_window in us (0 = none; netcfg needs a SYNC period);
  sync_overflow > 1 -> sync_counter (the same overflow value). A master node (role master, named `master`) with
  master.node_id and master.heartbeat_producer (ms).
- every slave: a node with node_id (else the DCF's [DeviceComissioning] NodeID, else skipped with a warning, as
  dcfgen skips it), heartbeat_producer (ms), heartbeat_multiplier (its own or options', when the master's
  consumer time int(producer x multiplier) ms is not netcfg's default 3 x: heartbeat_timeout) and
  `device: {eds: <dcf>}`. `dcf` is read relative to the bus.yml's
  folder (dcfgen runs there in ros2_canopen's CMake macros); `@BUS_CONFIG_PATH@` is replaced by that folder, as
  those macros replace it by '.'; other @VAR@ placeholders are errors. The importer does not know where the spec
  will be written unless told (`netcfg import -o` tells it): paths are then relative to the spec, else absolute
  (the comment above it keeps the bus.yml's spelling). A dcf
  that our emitter generated from a built-in profile (named in the bus.yml and in the file's [Comments]) becomes
  `device: <profile>` again, so a round trip rebuilds byte-identical device files.
- every enabled PDO a message: tpdo n -> producer the slave, consumer the master; rpdo n -> producer the master,
  consumer the slave. Keys left out keep the DCF's values, as dcfgen does (COB-ID, transmission type, inhibit time,
  event timer, mapping); a PDO slot the bus.yml does not mention but the DCF enables stays on the bus (warning).
  cob_id auto = the CiA 301 default (no `id` in the spec) for PDOs 1-4 and, for PDOs 5+, dcfgen's allocation from
  0x680 upwards in its processing order (file order; alphabetical node order after ros2_canopen's preprocessor);
  any other COB-ID becomes `id` (bit 29 = extended; bit 30, no RTR, is dropped). inhibit_time is in 100 us,
  event_timer in ms (CiA 301).
- timing: TPDOs are timed by their transmission type (netcfg derives it); an event-driven TPDO without an inhibit
  time has no bound on its rate and becomes `type: on-demand` (warning; an event timer's sends are still counted).
  An RPDO is sent by the master: synchronous types every n SYNC periods, type 0 at most once per SYNC,
  event-driven ones with event_timer every event_timer (dcfgen gives the master's mirrored TPDO that timer),
  without one once per SYNC period: the ros2_canopen drivers write their targets every control cycle, which runs on
  the SYNC period.
- `sdo` writes: netcfg does not send SDOs; they stay as comments with one warning per node, and a write to an
  object netcfg configures itself (SYNC 0x1005-0x1007, heartbeat 0x1017, PDO parameters 0x1400-0x1BFF) contradicts
  the timing netcfg proves: an error (with --lenient a warning).
- Lely settings that do not change the traffic (boot, identity checks, heartbeat consumers, error behaviour...)
  and ros2_canopen driver settings (driver, package, scaling...) stay as comments. Any other key is an error naming
  file, line, key and node (with --lenient a warning per key).
- `# netcfg: ...` comments that our emitter writes restore what a bus.yml cannot say: the system, bus and master
  names, the read window, message names and timing, signal names.
Every item carries a comment saying where it came from (`bus.yml line 12: joint1.tpdo.1`). The spec is checked
against the devices before anything is written: its errors point into the bus.yml.
"""

from __future__ import annotations

import os
import re
from collections.abc import Set
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from netcfg import cia301
from netcfg.devices import builtin_profile_names
from netcfg.devices.eds import EdsError, object_dictionary
from netcfg.diagnostics import Collector, Position
from netcfg.importers import Imported, ImportOptions
from netcfg.importers import Path as SpecPath
from netcfg.importers.bus_yml_dcf import DeviceFile, Slot
from netcfg.importers.bus_yml_keys import (
    _PLACEHOLDER_ANY,
    FIRST_AUTO_COB_ID,
    HEADER_KEYS,
    LAST_AUTO_COB_ID,
    MAPPING_KEYS,
    MASTER_KEPT,
    MASTER_MAPPED,
    NODE_ID_LIMITS,
    OPTIONS_KEYS,
    PDO_KEYS,
    PDO_NOTE_KEYS,
    PLACEHOLDER,
    ROS_KEYS,
    SDO_KEYS,
    SLAVE_KEPT,
    SLAVE_MAPPED,
    BusPath,
    check_name_ok,
    default_timing,
    duration,
    duration_ns,
    parse_annotation,
    safe_name,
)
from netcfg.importers.bus_yml_notes import apply_spec_notes, read_spec_notes
from netcfg.inputs import InputError, check_input_path, decode_text, read_input_bytes
from netcfg.spec.load import report_validation_errors
from netcfg.spec.source import SourceMap, load_yaml


# -- the importer ----------------------------------------------------------------------------------------------------
@dataclass
class Val:
    """A bus.yml value and where it was written (defaults merged into a node keep the defaults' path)."""

    value: Any
    path: BusPath


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


class BusYmlImporter:
    def __init__(self, path: Path, options: ImportOptions, diags: Collector) -> None:
        self.path = path
        self.file = str(path)
        self.name = path.name
        self.folder = path.parent
        self.options = options
        self.heartbeat_multiplier: Val | None = None  # options.heartbeat_multiplier, for every slave
        self.d = diags
        self.smap = SourceMap(self.file)
        self.lines: list[str] = []
        self.ros = False  # ros2_canopen dialect (defaults/nodes)
        self.origin: dict[SpecPath, BusPath] = {}  # spec path -> bus.yml path: positions of later errors
        self.comments: dict[SpecPath, str] = {}
        self.nodes: list[dict[str, Any]] = []
        self.messages: list[dict[str, Any]] = []
        self.auto_cob_id = FIRST_AUTO_COB_ID
        self.auto_ids: dict[tuple[str, str, int], int] = {}
        self.device_files: dict[int, DeviceFile] = {}  # id of a parsed object dictionary -> its one DeviceFile
        self.sync_us = 0

    # -- diagnostics and small readers ---------------------------------------------------------------------------
    def link(self, spath: SpecPath, bpath: BusPath) -> None:
        """The spec item at spath came from bpath: its comment and its errors point there."""
        self.origin[spath] = bpath

    def link_note(self, spath: SpecPath, line: int) -> None:
        """The spec item at spath came from the `# netcfg-spec:` comment on this line."""
        bpath = ("# netcfg-spec", line)
        self.smap.record(bpath, _mark(self.file, Position(self.file, line, 1)))
        self.link(spath, bpath)

    def warn_note(self, message: str, line: int) -> None:
        self.d.add("bus-yml-note", message, Position(self.file, line, 1), "warning")

    def at(self, bpath: BusPath, key: bool = False) -> Position:
        return self.smap.key_at(bpath) if key else self.smap.at(bpath)

    def err(self, code: str, message: str, bpath: BusPath, key: bool = False) -> None:
        self.d.add(code, message, self.at(bpath, key))

    def warn(self, code: str, message: str, bpath: BusPath, key: bool = False) -> None:
        self.d.add(code, message, self.at(bpath, key), "warning")

    def strict(self, code: str, message: str, bpath: BusPath, key: bool = False) -> None:
        """What netcfg cannot map: an error, with --lenient a warning."""
        if self.options.lenient:
            self.warn(code, message + " (--lenient: kept as a comment)", bpath, key)
        else:
            self.err(code, message + "; fix it, or pass --lenient to keep it as a comment", bpath, key)

    def where(self, bpath: BusPath) -> str:
        dotted = ".".join(str(p) for p in bpath)
        return f"{self.name} line {self.at(bpath, key=True).line}: {dotted}"

    def note(self, bpath: BusPath, key: bool = True) -> dict[str, str]:
        """The `# netcfg:` comment on the line of bpath's key (or value)."""
        line = self.at(bpath, key).line
        return parse_annotation(self.lines[line - 1]) if 0 < line <= len(self.lines) else {}

    def integer(self, val: Val, what: str, lo: int, hi: int) -> int | None:
        v = val.value
        if isinstance(v, bool) or not isinstance(v, int):
            self.err("bus-yml-value", f"{what} must be a whole number, not {v!r}", val.path)
            return None
        if not lo <= v <= hi:
            self.err("bus-yml-value", f"{what} must be {lo}..{hi}, not {v}", val.path)
            return None
        return v

    def mapping(self, val: Val, what: str) -> dict[str, Any] | None:
        if not isinstance(val.value, dict):
            self.err("bus-yml-value", f"{what} must be a mapping of keys to values", val.path)
            return None
        return val.value

    def sub(self, cfg: dict[Any, Any], path: BusPath) -> dict[str, Val]:
        return {str(k): Val(v, (*path, str(k))) for k, v in cfg.items()}

    def keys(self, cfg: dict[str, Val], used: Set[str], kept: Set[str], owner: str, into: list[str]) -> None:
        """Unknown keys are errors (--lenient: warnings); known ones netcfg does not use become comment lines."""
        for key, val in cfg.items():
            if key in used:
                continue
            shown = val.value if not isinstance(val.value, (dict, list)) else f"... (line {self.at(val.path).line})"
            if key in kept:
                into.append(f"{key}: {shown}")
                continue
            self.strict("unknown-key", f"unknown key '{key}' in {owner}", val.path, key=True)
            into.append(f"{key}: {shown} (unknown key)")

    # -- the whole file ------------------------------------------------------------------------------------------
    def run(self) -> Imported | None:
        raw = read_input_bytes(self.path, "bus.yml")  # refuses devices, FIFOs and oversized files (exit 2)
        try:
            text = decode_text(raw, self.path, "bus.yml")
        except InputError as exc:
            what = "is not UTF-8 text; save it as UTF-8" if "UTF-8" in exc.message else "contains a NUL byte"
            self.d.add("encoding", f"{self.name} {what}", Position(self.file, exc.line or 1, 1))
            return None
        self.lines = text.splitlines()
        data, self.smap = load_yaml(text, self.file, self.d)
        if data is None or self.d.errors:
            return None
        if not isinstance(data, dict):
            self.err("not-a-mapping", "a bus.yml is a mapping with keys options, master and one per slave", ())
            return None
        header = self.header()
        top = self.sub(data, ())
        self.ros = "nodes" in top or "defaults" in top
        if "master" not in top:
            self.err("bus-yml-master", f"{self.name} has no 'master' section; dcfgen needs one", ())
            return None
        slaves = self.slaves(top)
        master = self.mapping(top["master"], "master")
        if master is None:
            return None
        bus = header.get("bus") or "can0"
        master_name = header.get("master") or ("canopen_master" if "master" in slaves else "master")
        spec: dict[str, Any] = {"system": header.get("system") or self.system_name()}
        self.origin[("system",)] = ()
        master_cfg = self.sub(master, ("master",))
        spec["buses"] = [self.bus(bus, master_cfg, header, top.get("options"))]
        self.nodes.append(self.master_node(master_name, bus, master_cfg))
        if self.sync_us <= 0:
            return None
        # dcfgen numbers 'cob_id: auto' PDOs 5+ in the order it walks the slaves: the file's, or alphabetical after
        # ros2_canopen's preprocessor (its yaml.dump sorts the keys)
        for name in sorted(slaves) if self.ros else slaves:
            self.allocate(name, slaves[name][1])
        for name, (own, cfg) in slaves.items():
            added = self.slave(name, own, cfg, bus)
            if added is not None:
                self.pdos(name, own, cfg, added, master_name)
        spec["nodes"] = self.nodes
        spec["messages"] = self.messages
        if self.d.errors:
            return None
        apply_spec_notes(spec, read_spec_notes(self.lines, self.file, self.d), self.link_note, self.warn_note)
        self.validate(spec)
        if self.d.errors:
            return None
        return spec, self.comments

    def header(self) -> dict[str, str]:
        """The `# netcfg:` comments before the first YAML line (netcfg's bus.yml emitter writes them)."""
        out: dict[str, str] = {}
        for n, line in enumerate(self.lines, 1):
            if line.strip() and not line.lstrip().startswith("#"):
                break
            for key, value in parse_annotation(line).items():
                pos = Position(self.file, n, 1)
                if key not in HEADER_KEYS:
                    self.d.add("bus-yml-note", f"unknown '# netcfg:' key '{key}' ignored", pos, "warning")
                elif key in ("system", "bus", "master", "sync_producer") and not check_name_ok(value):
                    self.d.add("bus-yml-note", f"'# netcfg:' {key}={value} is not a safe name; ignored", pos, "warning")
                else:
                    out[key] = value
        return out

    def system_name(self) -> str:
        stem = self.path.stem
        base = self.path.resolve().parent.name if stem.lower() == "bus" else stem
        return safe_name(base, "bus")

    def slaves(self, top: dict[str, Val]) -> dict[str, tuple[BusPath, dict[str, Val]]]:
        """Slave name -> (its own path, its keys: defaults merged (ros2_canopen) or as written (Lely))."""
        if "options" in top:
            opts = self.mapping(top["options"], "options")
            if opts is not None:
                given = self.sub(opts, ("options",))
                self.keys(given, OPTIONS_KEYS, set(), "options", [])
                self.heartbeat_multiplier = given.get("heartbeat_multiplier")
        out: dict[str, tuple[BusPath, dict[str, Val]]] = {}
        if not self.ros:  # Lely dcfgen: every other top-level key is a slave
            for key, val in top.items():
                if key not in ("options", "master") and not key.startswith("."):
                    cfg = self.mapping(val, f"slave '{key}'")
                    if cfg is not None:
                        out[key] = ((key,), self.sub(cfg, (key,)))
            return out
        for key, val in top.items():
            if key not in ("options", "master", "defaults", "nodes") and not key.startswith("."):
                self.strict(
                    "unknown-key",
                    f"unknown top-level key '{key}': with 'nodes:' (ros2_canopen) every slave goes under 'nodes'",
                    val.path,
                    key=True,
                )
        defaults: dict[str, Val] = {}
        if "defaults" in top:
            d = self.mapping(top["defaults"], "defaults")
            defaults = self.sub(d, ("defaults",)) if d is not None else {}
        nodes = top.get("nodes", Val({}, ("nodes",)))
        items: list[tuple[str, Any, BusPath]] = []
        if isinstance(nodes.value, dict):
            items = [(str(k), v, ("nodes", str(k))) for k, v in nodes.value.items()]
        elif isinstance(nodes.value, list):  # the documentation's '- name: {...}' form
            for i, item in enumerate(nodes.value):
                if not isinstance(item, dict) or len(item) != 1:
                    self.err("bus-yml-value", "each item of 'nodes' is one 'name: {settings}' mapping", ("nodes", i))
                    continue
                ((k, v),) = item.items()
                items.append((str(k), v, ("nodes", i, str(k))))
        else:
            self.err("bus-yml-value", "'nodes' must map slave names to their settings", nodes.path)
        for name, cfg, path in items:
            if name in out:
                self.err("duplicate-name", f"slave '{name}' appears twice in 'nodes'", path, key=True)
                continue
            own = self.mapping(Val({} if cfg is None else cfg, path), f"node '{name}'")
            if own is None:
                continue
            overridden = sorted(str(k) for k in own if str(k) in defaults)
            if overridden:
                self.warn(
                    "bus-yml-defaults",
                    f"node '{name}' overrides defaults {', '.join(overridden)}: netcfg takes the node's value, but "
                    "ros2_canopen's preprocessor (cogen) lets 'defaults' win; check which one the robot runs with",
                    path,
                    key=True,
                )
            out[name] = (path, {**defaults, **self.sub(own, path)})
        return out

    # -- master and bus ------------------------------------------------------------------------------------------
    def bus(self, name: str, master: dict[str, Val], header: dict[str, str], options: Val | None) -> dict[str, Any]:
        path: SpecPath = ("buses", 0)
        self.origin[path] = ("master",)
        kbit = 1000  # dcfgen's default baudrate
        if "baudrate" in master:
            kbit = self.integer(master["baudrate"], "master.baudrate (kbit/s)", 1, 1_000_000) or kbit
            self.link((*path, "bitrate"), master["baudrate"].path)
        bitrate = f"{kbit} kbit/s"
        lines = [self.where(("master",)) + " (bit rate and SYNC)"]
        if self.options.bitrate is not None:
            bitrate = f"{self.options.bitrate} bit/s"
            lines.append(f"bit rate from the command line; {self.name} says {kbit} kbit/s")
        canopen: dict[str, Any] = {}
        sync = master.get("sync_period")
        if sync is None or sync.value == 0:
            self.err(
                "bus-yml-sync",
                "master.sync_period is not set (dcfgen's default 0 = no SYNC); netcfg times a CANopen bus by its "
                "SYNC cycle: give the SYNC period in microseconds, e.g. 'sync_period: 10000'",
                sync.path if sync is not None else ("master",),
                key=sync is None,
            )
        else:
            self.sync_us = self.integer(sync, "master.sync_period (us)", 1, 0xFFFFFFFF) or 0
            canopen["sync_period"] = duration(self.sync_us)
            self.link((*path, "canopen", "sync_period"), sync.path)
        window = master.get("sync_window")
        if window is not None and (w := self.integer(window, "master.sync_window (us)", 0, 0xFFFFFFFF)):
            canopen["sync_window"] = duration(w)
            self.link((*path, "canopen", "sync_window"), window.path)
        if header.get("read_window_ns", "").isdigit():
            canopen["read_window"] = duration_ns(int(header["read_window_ns"]))
        if re.fullmatch(r"0x[0-9A-Fa-f]{1,3}", header.get("sync_id", "")):
            canopen["sync_id"] = int(header["sync_id"], 16)
        if "sync_producer" in header:
            canopen["sync_producer"] = header["sync_producer"]
        overflow = master.get("sync_overflow")
        if overflow is not None and (o := self.integer(overflow, "master.sync_overflow", 0, 240)) and o > 1:
            canopen["sync_counter"] = o  # CiA 301 0x1019: 2..240 make SYNC carry a counter byte up to o
            self.link((*path, "canopen", "sync_counter"), overflow.path)
        if options is not None and isinstance(options.value, dict) and options.value:
            shown = ", ".join(f"{k}: {v}" for k, v in options.value.items())
            lines.append(f"options: {shown} (where dcfgen's files go at run time; netcfg does not need it)")
        self.comments[path] = "\n".join(lines)
        return {"name": name, "protocol": "canopen", "bitrate": bitrate, "canopen": canopen}

    def master_node(self, name: str, bus: str, master: dict[str, Val]) -> dict[str, Any]:
        path: SpecPath = ("nodes", 0)
        self.origin[path] = ("master",)
        node: dict[str, Any] = {"name": name, "role": "master"}
        kept: list[str] = []
        self.keys(master, MASTER_MAPPED, MASTER_KEPT | ROS_KEYS, "master", kept)
        if "node_id" not in master:
            self.err(
                "node-id",
                "master.node_id is not set (dcfgen's default 255 means unconfigured); give the master's node id "
                f"{NODE_ID_LIMITS[0]}..{NODE_ID_LIMITS[1]}",
                ("master",),
                key=True,
            )
        elif self.integer(master["node_id"], "master.node_id (a CANopen node id)", *NODE_ID_LIMITS) is not None:
            node["node_id"] = master["node_id"].value
            self.link((*path, "node_id"), master["node_id"].path)
        node["buses"] = [bus]
        self.heartbeat(node, master.get("heartbeat_producer"), path)
        lines = [self.where(("master",))]
        if kept:
            lines.append("kept from the bus.yml (netcfg does not use them): " + "; ".join(kept))
        self.comments[path] = "\n".join(lines)
        return node

    def heartbeat(self, node: dict[str, Any], val: Val | None, path: SpecPath) -> None:
        if val is None:
            return
        ms = self.integer(val, "heartbeat_producer (ms)", 0, 0xFFFF)
        if ms:
            node["heartbeat"] = f"{ms} ms"
            self.link((*path, "heartbeat"), val.path)

    def heartbeat_timeout(self, node: dict[str, Any], val: Val | None, path: SpecPath) -> None:
        """dcfgen's heartbeat_multiplier (default 3.0): the master's consumer time for the slave is the integer part of
        producer x multiplier, in ms; netcfg's default is the same 3 x, so only another factor is written."""
        if val is None or "heartbeat" not in node:
            return
        factor = val.value
        if isinstance(factor, bool) or not isinstance(factor, (int, float)) or not factor > 1:
            self.err("bus-yml-value", f"heartbeat_multiplier must be a number above 1, not {factor!r}", val.path)
            return
        producer = int(str(node["heartbeat"]).split()[0])
        timeout = int(producer * factor)
        if timeout != 3 * producer:
            node["heartbeat_timeout"] = f"{timeout} ms"
            self.link((*path, "heartbeat_timeout"), val.path)

    # -- slaves --------------------------------------------------------------------------------------------------
    def slave(self, name: str, own: BusPath, cfg: dict[str, Val], bus: str) -> tuple[DeviceFile, int, str] | None:
        """Add the node; -> (its device file, node id, spec name), or None when it cannot be used."""
        kept: list[str] = []
        self.keys(cfg, SLAVE_MAPPED, SLAVE_KEPT | ROS_KEYS, f"node '{name}'", kept)
        dcf = cfg.get("dcf")
        if dcf is None:
            self.err("bus-yml-dcf", f"node '{name}' has no 'dcf' (its EDS/DCF file), which dcfgen needs", own, True)
            return None
        device, file = self.device_file(name, dcf)
        if device is None or file is None:
            return None
        node_name = safe_name(name, "node")
        path: SpecPath = ("nodes", len(self.nodes))
        self.origin[path] = own
        node: dict[str, Any] = {"name": node_name}
        if "node_id" in cfg:
            got = self.integer(cfg["node_id"], f"node_id of node '{name}' (a CANopen node id)", *NODE_ID_LIMITS)
            if got is None:
                return None
            node["node_id"] = nid = got
            self.link((*path, "node_id"), cfg["node_id"].path)
        elif device.node_id is not None:
            node["node_id"] = nid = device.node_id
            kept.append(f"node id {nid} from the dcf's [DeviceComissioning]")
        else:
            self.warn(
                "node-id",
                f"node '{name}' has no node_id, neither in {self.name} nor in its dcf; dcfgen ignores such a slave, "
                "and so does netcfg",
                own,
                key=True,
            )
            return None
        node["buses"] = [bus]
        lines = [self.where(own)]
        if node_name != name:
            lines.append(f"named '{name}' in {self.name}")
        hint = self.note(own).get("device")
        if hint and hint in builtin_profile_names() and f"(builtin:{hint})" in device.comments:
            node["device"] = hint  # the dcf was generated by netcfg from this built-in profile
            lines.append(f"dcf: {dcf.value} (generated by netcfg from the built-in profile {hint})")
        else:
            if hint:
                self.warn(
                    "bus-yml-note", f"'# netcfg: device={hint}' does not match dcf {dcf.value}; using the file", own
                )
            node["device"] = {"eds": file.as_posix()}
            lines.append(f"dcf: {dcf.value}")
        self.link((*path, "device"), dcf.path)
        self.link((*path, "device", "eds"), dcf.path)
        self.heartbeat(node, cfg.get("heartbeat_producer"), path)
        self.heartbeat_timeout(node, cfg.get("heartbeat_multiplier") or self.heartbeat_multiplier, path)
        lines.extend(self.sdos(name, cfg.get("sdo"), device))
        if kept:
            lines.append("kept from the bus.yml (netcfg does not use them): " + "; ".join(kept))
        self.comments[path] = "\n".join(lines)
        self.nodes.append(node)
        return device, nid, node_name

    def device_file(self, name: str, dcf: Val) -> tuple[DeviceFile | None, Path | None]:
        if not isinstance(dcf.value, str) or not dcf.value.strip():
            self.err("bus-yml-dcf", f"'dcf' of node '{name}' must be a file name", dcf.path)
            return None, None
        rel = dcf.value.replace(PLACEHOLDER, ".")
        unknown = _PLACEHOLDER_ANY.search(rel)
        if unknown:
            self.err(
                "bus-yml-dcf",
                f"'dcf' of node '{name}' uses {unknown.group(0)}; netcfg replaces only {PLACEHOLDER} (by the "
                "bus.yml's folder, as ros2_canopen's CMake macros do)",
                dcf.path,
            )
            return None, None
        try:
            file = check_input_path(self.folder, rel, "dcf file")
        except ValueError as exc:
            self.err("bus-yml-dcf", f"node '{name}': {exc} (dcf paths are relative to the folder of {self.name})",
                     dcf.path)
            return None, None
        try:
            od = object_dictionary(file)  # parsed once, shared with resolve's device profiles
            device = self.device_files.get(id(od))
            if device is None:
                device = self.device_files[id(od)] = DeviceFile(od)  # it keeps od, so the id stays its own
            return device, file
        except OSError:
            raise
        except EdsError as exc:
            self.err("eds-invalid", f"dcf file '{dcf.value}' of node '{name}': {exc}", dcf.path)
            return None, None
        except Exception as exc:  # canopen raises many kinds for bad files
            self.err("eds-invalid", f"dcf file '{dcf.value}' of node '{name}': canopen cannot read it: {exc}", dcf.path)
            return None, None

    def sdos(self, name: str, val: Val | None, device: DeviceFile) -> list[str]:
        """SDO writes: kept as comment lines (see the module docstring)."""
        if val is None:
            return []
        if not isinstance(val.value, list):
            self.err("bus-yml-value", f"'sdo' of node '{name}' is a list of {{index, sub_index, value}}", val.path)
            return []
        lines = []
        for i, item in enumerate(val.value):
            ipath = (*val.path, i)
            if not isinstance(item, dict):
                self.err("bus-yml-value", "an SDO write is {index: 0x..., sub_index: n, value: v}", ipath)
                continue
            cfg = self.sub(item, ipath)
            self.keys(cfg, SDO_KEYS, set(), f"an SDO write of node '{name}'", [])
            if "index" not in cfg:
                self.err("bus-yml-value", f"an SDO write of node '{name}' needs 'index'", ipath)
                continue
            index = self.integer(cfg["index"], "sdo index", 0, 0xFFFF)
            sub = self.integer(cfg["sub_index"], "sdo sub_index", 0, 0xFF) if "sub_index" in cfg else 0
            if index is None or sub is None:
                continue
            value = cfg["value"].value if "value" in cfg else 0
            lines.append(f"sdo 0x{index:04X}:{sub} = {value} ({self.name} line {self.at(ipath).line})")
            if not device.has(index, sub):  # dcfgen stops here too
                self.err(
                    "bus-yml-sdo",
                    f"SDO write of node '{name}' to 0x{index:04X}:{sub}: its dcf has no such object",
                    ipath,
                )
            elif cia301.configured_from_bus(index):
                self.strict(
                    "bus-yml-sdo",
                    f"SDO write of node '{name}' to 0x{index:04X}:{sub}, which netcfg configures from the bus (SYNC, "
                    "heartbeat, PDOs): it would change the timing netcfg proves (say it with the bus.yml's keys)",
                    ipath,
                )
        if lines:
            self.warn(
                "bus-yml-sdo",
                f"node '{name}': {len(lines)} SDO write(s) kept as comments; netcfg does not send SDOs",
                val.path,
                key=True,
            )
        return lines

    # -- PDOs ----------------------------------------------------------------------------------------------------
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
            "name": named if check_name_ok(named) else safe_name(f"{p.node}_{p.kind}{p.number}", "pdo")
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
        for j, item in enumerate(val.value):
            ipath = (*val.path, j)
            if not isinstance(item, dict):
                self.err("bus-yml-value", f"a mapping entry of {label} is {{index: 0x6041, sub_index: 0}}", ipath)
                continue
            cfg = self.sub(item, ipath)
            self.keys(cfg, MAPPING_KEYS, set(), f"a mapping entry of {label}", [])
            if "index" not in cfg:
                self.err("bus-yml-value", f"a mapping entry of {label} needs 'index'", ipath)
                continue
            index = self.integer(cfg["index"], "mapping index", 0, 0xFFFF)
            sub = self.integer(cfg["sub_index"], "mapping sub_index", 0, 0xFF) if "sub_index" in cfg else 0
            if index is None or sub is None:
                continue
            ref: Any = index if sub == 0 else f"0x{index:04X}:{sub}"
            name = self.note(ipath, key=False).get("name", "")
            if check_name_ok(name):
                ref = {"object": f"0x{index:04X}:{sub}", "name": name}
            self.link((*mpath, "pdo", "map", len(out)), ipath)
            out.append(ref)
        return out

    # -- check the spec against the devices, with positions in the bus.yml ---------------------------------------
    def validate(self, spec: dict[str, Any]) -> None:
        from netcfg.resolve import resolve
        from netcfg.spec.schema import Spec

        smap = SourceMap(self.file)
        smap.record((), _mark(self.file, self.at(())))
        for spath, bpath in self.origin.items():
            smap.record(spath, _mark(self.file, self.at(bpath)), _mark(self.file, self.at(bpath, key=True)))
        try:
            checked = Spec.model_validate(spec)
        except ValidationError as exc:
            report_validation_errors(exc, smap, self.d)
            return
        resolve(checked, smap, self.d, self.folder)


def _mark(file: str, pos: Position) -> yaml.Mark:
    return yaml.Mark(file, 0, pos.line - 1, pos.column - 1, None, 0)  # type: ignore[arg-type]


def import_bus_yml(path: Path, options: ImportOptions, diags: Collector) -> Imported | None:
    """Read a Lely dcfgen / ros2_canopen bus.yml; None (with errors in diags) when it cannot be imported.

    OSError propagates (the CLI turns it into exit code 2), and so does a bug in netcfg: the CLI reports that
    once, the same way for every importer (exit code 2, no traceback unless NETCFG_DEBUG is set)."""
    imported = BusYmlImporter(path, options, diags).run()
    if imported is not None and options.output is not None:
        _relative_device_paths(imported[0], Path(options.output).resolve().parent)
    return imported


def _relative_device_paths(data: dict[str, Any], spec_folder: Path) -> None:
    """The spec names EDS files relative to itself (it is read that way), so the imported spec can move with them."""
    for node in data.get("nodes", []):
        device = node.get("device")
        if isinstance(device, dict) and "eds" in device:
            device["eds"] = Path(os.path.relpath(device["eds"], spec_folder)).as_posix()
