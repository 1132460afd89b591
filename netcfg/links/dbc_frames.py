"""The CAN links' frames as cantools' DBC messages carry them: the one place netcfg speaks cantools' frame format.

A DBC file says that a frame is CAN FD by its VFrameFormat attribute (StandardCAN_FD or ExtendedCAN_FD, Vector's DBC
attributes), which cantools reads into and writes from `Message.is_fd` (cantools 45: formats/dbc/dbc_loader.py reads
it, dbc_writer.py writes every frame's VFrameFormat on a bus whose BusType is "CAN FD"). Frames of netcfg's own say
`fd`. The importer and the DBC emitter take a DBC frame's format from here and give theirs to cantools through here.
"""

from __future__ import annotations

from typing import Any

import cantools.database.can as cdb

from netcfg.timing.frames import CAN_MAX_PAYLOAD


def fd_declared(msg: cdb.Message) -> bool:
    """The DBC declares the frame CAN FD (its VFrameFormat)."""
    return bool(msg.is_fd)


def fd_frame(msg: cdb.Message) -> bool:
    """The frame is CAN FD: declared so, or longer than the 8 bytes a classical frame carries (ISO 11898-1), whatever
    the file declares."""
    return fd_declared(msg) or msg.length > CAN_MAX_PAYLOAD


def message(fd: bool, **fields: Any) -> cdb.Message:
    """A cantools Message of one of netcfg's frames: `fd` its CAN FD format, the rest cantools' own keywords."""
    return cdb.Message(is_fd=fd, **fields)
