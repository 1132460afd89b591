"""How netcfg's own CANopen frames travel: a leaf the resolver and the simulator's drills both ask, importing only the
link layer."""

from __future__ import annotations

from netcfg import links


def fd_services(bus: links.OnALink) -> bool:
    """Whether netcfg's own CANopen frames on the bus (SYNC, heartbeats, EMCY, boot-up, NMT) are CAN FD frames with
    bit-rate switch: on a CANopen FD bus (link: can-fd) they are, as a PDO is unless it says fd: false. A CANopen FD
    device's controller runs in CAN FD mode; whether CiA 1301 lets these services go as classical frames too is not
    decided here (the standard's clause could not be consulted), and either way the analysis and the simulator time
    them as sent. The resolver asks it of the spec's bus, the simulator's drills of runtime.json's."""
    return links.of(bus).data_phase
