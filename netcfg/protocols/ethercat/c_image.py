"""ethercat/<bus>_image.h: the process image of an EtherCAT segment for an RT master or an MCU: the IOmap's sizes,
each slave's identity and place in it, and every entry's byte offset, bit, width and C type."""

from __future__ import annotations

import re
from typing import Any

from netcfg import model
from netcfg.protocols.ethercat.ros2 import channel_type
from netcfg.protocols.ethercat.segment import Entry, segments
from netcfg.templating import render

C_TYPES = {"bool": "uint8_t", "float": "float", "double": "double"}


def ident(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").upper() or "X"


def c_type(e: Entry) -> str:
    t = channel_type(e.index, e.bits, e.data_type)
    if t in C_TYPES:
        return C_TYPES[t]
    if t.startswith(("int", "uint")):
        return f"{t}_t"
    return "uint8_t"  # bit fields and gaps: read through the bit and width


def emit(m: model.Model, report: dict[str, Any]) -> dict[str, bytes]:
    files = {}
    for bus, seg in segments(m):
        prefix = f"ECAT_{ident(bus.name)}"
        slaves = []
        for s in seg.slaves:
            entries = []
            for direction, image, base in (("out", seg.outputs, 0), ("in", seg.inputs, seg.out_bytes)):
                for e in image:
                    if e.slave != s.node or e.padding:
                        continue
                    bit = base * 8 + e.bit_offset
                    name = f"{prefix}_{ident(s.node)}_{direction.upper()}_{e.index:04X}_{e.sub:02X}_{ident(e.name)}"
                    entries.append(
                        {
                            "name": name,
                            "offset": bit // 8,
                            "bit": bit % 8,
                            "bits": e.bits,
                            "type": c_type(e),
                            "what": f"0x{e.index:04X}:{e.sub} {e.name}",
                        }
                    )
            slaves.append({"node": s.node, "prefix": f"{prefix}_{ident(s.node)}", "slave": s, "entries": entries})
        files[f"ethercat/{bus.name}_image.h"] = render(
            "ethercat_image.h.j2",
            system=m.system,
            bus=bus.name,
            guard=f"NETCFG_{ident(m.system)}_{ident(bus.name)}",
            prefix=prefix,
            seg=seg,
            slaves=slaves,
        )
    return files
