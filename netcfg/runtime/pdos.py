"""The PDO records: what a PDO maps and its slot's parameters, as runtime.json has them and the spec's model holds
them (netcfg.model.Pdo is PdoParameters; runtime.json's Pdo adds the COB-ID, which the model has as the message's
id). EtherCAT's PDO entries (netcfg.protocols.ethercat.esi) are mapped objects too."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = ["MappedObject", "Pdo", "PdoEntry", "PdoParameters"]


@dataclass(frozen=True)
class MappedObject:
    """An object-dictionary entry a PDO maps: index, sub-index, length and name. CiA 301 PDOs and EtherCAT's
    (CANopen over EtherCAT, ETG.2000: netcfg.protocols.ethercat.esi) address their objects alike."""

    index: int
    sub: int
    bits: int
    name: str


@dataclass(frozen=True)
class PdoEntry(MappedObject):  # the spec's model maps the same records (netcfg.model.Pdo)
    data_type: int  # CiA 301 data type code


@dataclass(frozen=True)
class PdoParameters:
    """A PDO slot's communication and mapping parameters (CiA 301 0x14xx/0x18xx, 0x16xx/0x1Axx): the spec's model
    holds a message's PDO as this (netcfg.model.Pdo), runtime.json as the Pdo below."""

    kind: Literal["tpdo", "rpdo"]
    number: int
    node: str  # the node whose TPDO/RPDO slot this is
    transmission: int
    inhibit_100us: int | None
    event_timer_ms: int | None
    sync_start: int | None
    entries: tuple[PdoEntry, ...]


@dataclass(frozen=True)
class Pdo(PdoParameters):
    # the 32-bit value of the slot's COB-ID (0x14xx/0x18xx sub 1), CiA 301 flag bits included, as the node's DCF
    # has it (the model's is its message's id); None in files written before it
    cob_id: int | None = None
