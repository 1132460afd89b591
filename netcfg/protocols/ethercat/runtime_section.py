"""runtime.json's section of an EtherCAT segment: what a SOEM master (through pysoem) applies in each slave's
configuration hook (the PO2SO hook, in PRE-OP): the CoE start-up SDOs, then the sync managers, FMMUs and DC
activation, and where each entry of the process image lies; and what the simulator runs the cycle with and holds
it against (netcfg.sim.ethercat): each slave's forwarding delay and cable, the frames, and the analysis' bounds
(the frame's return to the master, its passing each slave, distributed clocks' precision). Checked against
netcfg.runtime.schema.ETHERCAT."""

from __future__ import annotations

from typing import Any

from netcfg import model
from netcfg.protocols.ethercat.analysis import DC_PRECISION_NS, segment_timing
from netcfg.protocols.ethercat.messages import pdo_messages, read_offset_ns
from netcfg.protocols.ethercat.segment import Segment, Slave

ASSIGN = {"rx": 0x1C12, "tx": 0x1C13}


def startup_sdos(s: Slave) -> list[dict[str, int]]:
    """CoE downloads in the order ETG.1020 asks: each PDO mapping the master writes (sub-index 0 cleared, the
    entries, the count), then each PDO assignment (cleared, the PDOs, the count). A device whose assignment objects
    are read-only (a fixed-PDO slave) gets no assignment writes."""
    out: list[dict[str, int]] = []

    def sdo(index: int, sub: int, bits: int, value: int) -> None:
        out.append({"index": index, "sub": sub, "bits": bits, "value": value})

    for index, entries in s.pdo_mappings.items():
        sdo(index, 0, 8, 0)
        for k, (obj, sub, bits) in enumerate(entries, 1):
            sdo(index, k, 32, obj << 16 | sub << 8 | bits)
        sdo(index, 0, 8, len(entries))
    if s.assign_writable:
        for side, pdos in (("rx", s.rx), ("tx", s.tx)):
            sdo(ASSIGN[side], 0, 8, 0)
            for k, p in enumerate(pdos, 1):
                sdo(ASSIGN[side], k, 16, p.index)
            sdo(ASSIGN[side], 0, 8, len(pdos))
    return out


def runtime_section(bus: model.Bus, seg: Segment) -> dict[str, Any]:
    timing = segment_timing(bus, seg)
    slaves = []
    for s, passed in zip(seg.slaves, timing.passed_ns):
        sms = {sm.kind: sm for sm in s.sync_managers}
        fmmu = []
        if s.out_bytes and "Outputs" in sms:
            fmmu.append(
                {
                    "direction": "outputs",
                    "logical": s.out_offset,
                    "length": s.out_bytes,
                    "physical": sms["Outputs"].start,
                }
            )
        if s.in_bytes and "Inputs" in sms:
            fmmu.append(
                {
                    "direction": "inputs",
                    "logical": seg.out_bytes + s.in_offset,
                    "length": s.in_bytes,
                    "physical": sms["Inputs"].start,
                }
            )
        entries = [
            {
                "direction": direction,
                "pdo": e.pdo,
                "index": e.index,
                "sub": e.sub,
                "bits": e.bits,
                "name": e.name,
                "bit_offset": e.bit_offset,
            }
            for direction, image in (("outputs", seg.outputs), ("inputs", seg.inputs))
            for e in image
            if e.slave == s.node
        ]
        slaves.append(
            {
                "node": s.node,
                "position": s.position,
                "vendor_id": s.vendor_id,
                "product_code": s.product_code,
                "revision": s.revision,
                "device": s.device,
                "rxpdo": [p.index for p in s.rx],
                "txpdo": [p.index for p in s.tx],
                "sdo": startup_sdos(s),
                "sm": [
                    {
                        "number": sm.number,
                        "kind": sm.kind,
                        "start": sm.start,
                        "length": sm.length,
                        "control": sm.control,
                    }
                    for sm in s.sync_managers
                ],
                "fmmu": fmmu,
                "dc": {
                    "assign_activate": s.assign_activate,
                    "sync0_cycle_ns": seg.sync0_cycle_ns if s.assign_activate else 0,
                    "sync0_shift_ns": (s.sync0_shift_ns if s.sync0_shift_ns is not None else seg.sync0_shift_ns)
                    if s.assign_activate
                    else 0,
                },
                "entries": entries,
                "forwarding_ns": s.forwarding_ns,
                "cable_m": s.cable_m,
                "frame_passed_ns": passed,  # the analysis' bound: the last frame's end has passed the slave
            }
        )
    out = {
        "cycle_ns": seg.cycle_ns,
        "sync0_cycle_ns": seg.sync0_cycle_ns,
        "sync0_shift_ns": seg.sync0_shift_ns,
        "master": seg.master,
        "master_jitter_ns": seg.master_jitter_ns,
        "out_bytes": seg.out_bytes,
        "in_bytes": seg.in_bytes,
        "slaves": slaves,
        "frames": [{"data_bytes": d, "wire_bytes": w} for d, w in zip(timing.frames, timing.frame_bytes)],
        "latency_ns": timing.latency_ns,  # the analysis' bound: the last frame back at the master
        "dc_precision_ns": DC_PRECISION_NS,
    }
    pdos = pdo_messages(bus, seg)
    if pdos:  # (only then: a segment without PDO messages writes what it always did)
        position = {s.node: k for k, s in enumerate(seg.slaves)}
        out["messages"] = [
            {
                "name": p.name,
                "slave": position[p.slave],
                "direction": p.direction,
                # from the master's send to the read of the slave's first input byte (netcfg.sim.ethercat's capture)
                "read_offset_ns": read_offset_ns(timing, p.logical, bus.bitrate) if p.direction == "inputs" else 0,
            }
            for p in pdos
        ]
    return out
