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

This module reads the file, its options, master and slaves (BusYmlImporter); the PDOs are
netcfg.importers.bus_yml_pdo's, the checked readers and diagnostics bus_yml_read's, the DCF slots bus_yml_dcf's,
the vocabulary bus_yml_keys' and the `# netcfg-spec:` notes bus_yml_notes'.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from netcfg import cia301
from netcfg.devices import builtin_profile_names
from netcfg.devices.eds import EdsError, object_dictionary
from netcfg.diagnostics import Collector, Position
from netcfg.importers import Imported, ImportOptions
from netcfg.importers import Path as SpecPath
from netcfg.importers.bus_yml_dcf import DeviceFile
from netcfg.importers.bus_yml_keys import (
    _PLACEHOLDER_ANY,
    HEADER_KEYS,
    JOINT_KEYS,
    MASTER_KEPT,
    MASTER_MAPPED,
    NODE_ID_LIMITS,
    OPTIONS_KEYS,
    PLACEHOLDER,
    ROS_KEYS,
    SDO_KEYS,
    SLAVE_KEPT,
    SLAVE_MAPPED,
    BusPath,
    duration,
    duration_ns,
    parse_annotation,
    ros2_canopen_scaling,
    safe_name,
)
from netcfg.importers.bus_yml_notes import apply_spec_notes, read_spec_notes
from netcfg.importers.bus_yml_pdo import BusYmlPdos
from netcfg.importers.bus_yml_read import Val, mark
from netcfg.inputs import InputError, check_input_path, decode_text, read_input_bytes
from netcfg.spec.load import report_validation_errors
from netcfg.spec.names import is_name
from netcfg.spec.source import SourceMap, load_yaml


class BusYmlImporter(BusYmlPdos):
    """One bus.yml: its options, master and slaves as the spec's bus and nodes (the PDOs: BusYmlPdos)."""

    def __init__(self, path: Path, options: ImportOptions, diags: Collector) -> None:
        super().__init__(path, options, diags)
        self.heartbeat_multiplier: Val | None = None  # options.heartbeat_multiplier, for every slave
        self.nodes: list[dict[str, Any]] = []
        self.device_files: dict[int, DeviceFile] = {}  # id of a parsed object dictionary -> its one DeviceFile
        self.joint_nodes: set[str] = set()  # the slaves a `# netcfg-spec:` joint names: their JOINT_KEYS are read
        self.joint_keys: dict[str, dict[str, Val]] = {}  # node -> its JOINT_KEYS as the file gives them

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
        notes = read_spec_notes(self.lines, self.file, self.d)
        self.joint_nodes = {
            str(item["joint"].get("node")) for _, item in notes if "joint" in item and isinstance(item["joint"], dict)
        }
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
        apply_spec_notes(spec, notes, self.link_note, self.warn_note)
        self.check_joint_keys(spec)
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
                elif key in ("system", "bus", "master", "sync_producer") and not is_name(value):
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
        joint = safe_name(name, "node") in self.joint_nodes
        self.keys(cfg, SLAVE_MAPPED | (JOINT_KEYS if joint else set()), SLAVE_KEPT | ROS_KEYS, f"node '{name}'", kept)
        if joint:
            self.joint_keys[safe_name(name, "node")] = {k: v for k, v in cfg.items() if k in JOINT_KEYS}
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

    def check_joint_keys(self, spec: dict[str, Any]) -> None:
        """A joint's drive's scaling in the file against the one its joint gives: a hand-edited factor is a warning,
        and the joint's (its gear and encoder, which a factor alone cannot tell apart) is what the spec keeps."""
        for joint in spec.get("joints", []):
            given = self.joint_keys.get(str(joint.get("node"))) if isinstance(joint, dict) else None
            if not given:
                continue
            try:
                expected = ros2_canopen_scaling(
                    float(joint.get("gear_ratio", 1.0)),
                    joint.get("encoder_counts"),
                    str(joint.get("velocity_unit", "rpm")),
                    joint.get("rated_torque"),
                    float(joint.get("zero", 0.0)),
                )
            except (TypeError, ValueError, ZeroDivisionError):  # the spec's check reports the joint's values
                continue
            for key, val in given.items():
                want = expected.get(key)
                if key in ("driver", "package") or want is None:
                    continue
                got = val.value
                if isinstance(got, bool) or not isinstance(got, (int, float)) or not math.isclose(got, want):
                    self.warn(
                        "bus-yml-joint",
                        f"{key} of node '{joint.get('node')}' is {got!r}, but joint '{joint.get('name')}' gives "
                        f"{want!r}; the joint's is kept",
                        val.path,
                    )

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
        shape = "an SDO write is {index: 0x..., sub_index: n, value: v}"
        for ipath, cfg, index, sub in self.objects(val, SDO_KEYS, f"an SDO write of node '{name}'", shape, "sdo"):
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

    # -- check the spec against the devices, with positions in the bus.yml ---------------------------------------
    def validate(self, spec: dict[str, Any]) -> None:
        from netcfg.resolve import resolve
        from netcfg.spec.schema import Spec

        smap = SourceMap(self.file)
        smap.record((), mark(self.file, self.at(())))
        for spath, bpath in self.origin.items():
            smap.record(spath, mark(self.file, self.at(bpath)), mark(self.file, self.at(bpath, key=True)))
        try:
            checked = Spec.model_validate(spec)
        except ValidationError as exc:
            report_validation_errors(exc, smap, self.d)
            return
        resolve(checked, smap, self.d, self.folder)



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
