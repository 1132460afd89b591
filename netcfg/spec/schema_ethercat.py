"""The spec language's EtherCAT segment (netcfg.protocols.ethercat): its slaves in wire order, their devices (an
ESI file or a built-in profile), PDO assignment and distributed clocks."""

from __future__ import annotations

from pydantic import Field

from netcfg.spec.fields import DurationField
from netcfg.spec.schema_types import Float, Int, Name, ObjectRef, SpecModel, _ns


class EthercatEsi(SpecModel):
    file: str = Field(description="path of the vendor's ESI file (ETG.2000 XML), relative to the spec")
    device: str | Int | None = Field(
        None, description="which <Device> of the file: its <Type> name or product code (default: the only one)"
    )



class EthercatPdo(SpecModel):
    """A PDO's mapping (0x16xx/0x1Axx) the master writes at start-up: for a profile drive, or an ESI PDO that is
    not Fixed."""

    index: Int = Field(ge=0x1600, le=0x1BFF, description="the PDO's mapping object: 0x1600.. (Rx), 0x1A00.. (Tx)")
    map: list[ObjectRef] = Field(min_length=1, description="mapped objects, first byte first")



class EthercatSlave(SpecModel):
    node: Name = Field(description="the node (in nodes:) this slave is")
    position: Int = Field(ge=0, le=65534, description="its place in the line: 0 next to the master, then 1, 2, ...")
    cable: Float = Field(0.0, ge=0, le=100, description="metres of cable from the previous device (100BASE-TX: <= 100)")
    forwarding_delay: DurationField | None = Field(
        None,
        description="what the slave adds to the frame's round trip (default by its ESI's Physics: 2 us an RJ45 "
        "slave, twice an EtherCAT coupler's typical propagation delay; 310 ns an E-bus terminal)",
    )
    esi: EthercatEsi | None = Field(None, description="the slave's ESI file and device in it")
    profile: Name | None = Field(None, description="a built-in CoE profile instead of an ESI: cia402, epos4")
    rxpdo: list[Int] | None = Field(
        None, description="PDO assignment of the outputs (0x1C12); default: the ESI's mandatory RxPDOs, else its first"
    )
    txpdo: list[Int] | None = Field(
        None, description="PDO assignment of the inputs (0x1C13); default: the ESI's mandatory TxPDOs, else its first"
    )
    pdos: list[EthercatPdo] = Field(default_factory=list, description="PDO mappings the master writes at start-up")
    opmode: str | None = Field(None, description="the ESI's <Dc><OpMode> by name (default: its first, if any)")
    assign_activate: Int | None = Field(
        None, ge=0, le=0xFFFF, description="DC activation (register 0x0980); default: the op mode's"
    )
    sync0_shift: DurationField | None = Field(None, description="this slave's SYNC0 shift (default: the bus's)")
    min_cycle: DurationField | None = Field(None, description="the slave's shortest cycle (its 0x1C32:05)")



class EthercatParams(SpecModel):
    cycle: DurationField = Field(description="the master's cycle: one exchange of the process image")
    master: Name | None = Field(None, description="the EtherCAT master (default: the node with role master)")
    slaves: list[EthercatSlave] = Field(min_length=1, description="the slaves in wire order")
    sync0_cycle: DurationField | None = Field(None, description="distributed clocks' SYNC0 period (default: cycle)")
    sync0_shift: DurationField | None = Field(
        None, description="SYNC0 after the cycle's start, when the slaves latch the outputs (default: half a cycle)"
    )
    master_jitter: DurationField = Field(
        default_factory=lambda: _ns(0), description="how late the master may send a cycle's first frame"
    )
