"""The trigger message's frame format, the one place that decides it: on a classical CAN link a classical data
frame (seed 002), on a CAN FD link a CAN FD frame with bit-rate switch, so that its EC-schedule bytes go at the data
bit rate like the synchronous frames it announces (ISO 11898-1:2015 lets a CAN FD bus carry either format; the
FD frame is the shorter for every data rate above the arbitration rate, which shortens the EC's fixed overhead).
The analysis (netcfg.timing.ftt.tm_bits), the simulator's master (sim.py) and the log checker (log.py) all ask
here, the compiler by the model's bus and the simulator and verify by runtime.json's `link`.

Its identifier is a standard (11-bit) one on every bus, 29-bit ones included (TM_EXTENDED): seed 002's trigger
message is a CAN 2.0A frame, and a standard frame outranks every extended frame of the same base identifier, which
the resolver's priority check relies on."""

from __future__ import annotations

TM_EXTENDED = False


def tm_fd(link: str) -> bool:
    """Whether the trigger message on a bus over `link` (netcfg.links.LINKS' name) is a CAN FD frame (with BRS)."""
    from netcfg.links import LINKS

    return LINKS[link].data_phase
