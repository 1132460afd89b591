"""netcfg.runtime: typed, read-only access to a runtime.json, for live masters and for the simulator.

A master runs this without the compiler: it imports only the standard library and netcfg.runtime.codec
(python-can only when a CAN frame is made or read), never netcfg.spec/resolve/model/timing/emit.

    cfg = netcfg.runtime.load("generated/allex2/runtime.json")
    cmd = cfg.message("hip_l_cmd")
    frame = cmd.to_can(target_velocity=1000, velocity_offset=-5)   # a can.Message
    msg, values = cfg.decode_can(frame)

Times are integer nanoseconds ("_ns"), as in the file. A message without signals (only a size) is read and
written through one unsigned field `<message>_raw` spanning its payload, the same name the DBC files use.

Version 1 has grown without changing the meaning of any key, so it is still version 1: nodes gained `identity`,
`eds`, `dcf`, `sdo_init`, `rpdo_count`, `tpdo_count`, `heartbeat_timeout_ns`, `on_loss`, `on_emcy`, `on_reboot`
(stop_node without it), `sdo_timeout_ns` (500 ms), `sdo_retries` (0) and `safe_stop`, CANopen buses `sync_overflow`
and `sync_completion_ns`, PDOs `cob_id`, flows `unsync_latency_min_ns` and `unsync_latency_max_ns`, messages
`sent_by` and `wcrt_unsync_ns`, FTT-CAN buses `windows`, CAN buses `errors` and `clock_tolerance_ppm`, FTT-CAN
schedule slots `allowance_ns`, Ethernet switch ports `queue`, Ethernet buses `nics` (each node's NIC queue) and
every bus its `link`. A file written before them still loads: their fields are then None (no `errors`: an error-free
bus; no `allowance_ns`: 0; no `clock_tolerance_ppm`: 100; no queue depths: the simulator's default; no `link`: the
one link its protocol then ran over, schema.EARLIER_LINKS; `sdo_init` None means "not stated", () means "nothing to
write"; `sent_by` None: no task sends the message as it finishes, it runs free; no `windows` means the asynchronous
window first), and a master falls back to what it did without them.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from netcfg.runtime.codec import CodecError
    from netcfg.runtime.config import (
        CAN_LINKS,  # noqa: F401  (not in __all__; kept importable from here)
        FD_PADDING,  # noqa: F401
        Bus,
        CanopenParams,
        EcSlot,
        ErrorAssumption,
        EthernetParams,
        Flow,
        FlowStep,
        FttParams,
        Message,
        Node,
        NodeIdentity,
        RuntimeConfig,
        SdoWrite,
        Signal,
        SrtEntry,
        Switch,
        SwitchPort,
        Task,
        Trigger,
        UdpPorts,
        UnknownNameError,
        interpolation_period,
        raw_signal_name,
    )
    from netcfg.runtime.loader import FORMAT, SUPPORTED_VERSIONS, RuntimeConfigError, load, parse, read_document
    from netcfg.runtime.pdos import Pdo, PdoEntry

__all__ = [
    "FORMAT",
    "SUPPORTED_VERSIONS",
    "Bus",
    "CanopenParams",
    "CodecError",
    "EcSlot",
    "ErrorAssumption",
    "EthernetParams",
    "Flow",
    "FlowStep",
    "FttParams",
    "Message",
    "Node",
    "NodeIdentity",
    "Pdo",
    "PdoEntry",
    "RuntimeConfig",
    "RuntimeConfigError",
    "SdoWrite",
    "Signal",
    "SrtEntry",
    "Switch",
    "SwitchPort",
    "Task",
    "Trigger",
    "UdpPorts",
    "UnknownNameError",
    "interpolation_period",
    "load",
    "parse",
    "raw_signal_name",
    "read_document",
]

# The names below load their module on first use (PEP 562): netcfg.runtime.codec alone (the DBC importer's
# payload layout) then costs no dataclasses, hashing or difflib it does not use. Every public name not the loader's,
# the codec's or the PDO records' is the config's.
_LOADER_NAMES = ("FORMAT", "SUPPORTED_VERSIONS", "RuntimeConfigError", "load", "parse", "read_document")
_HOME: dict[str, str] = dict.fromkeys((*__all__, "CAN_LINKS", "FD_PADDING"), "netcfg.runtime.config")
_HOME.update(dict.fromkeys(_LOADER_NAMES, "netcfg.runtime.loader"))
_HOME["CodecError"] = "netcfg.runtime.codec"
_HOME.update(dict.fromkeys(("Pdo", "PdoEntry"), "netcfg.runtime.pdos"))


def __getattr__(name: str) -> Any:
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value  # later look-ups find it directly
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOME})
