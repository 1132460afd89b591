"""The CiA 402 (IEC 61800-7-201) power drive state machine, from both ends: the drive's and the master's.

Both ends speak through two objects: the master writes commands into the controlword (0x6040) and reads the state
from the statusword (0x6041). The state names, statusword masks and controlword commands are the `canopen` package's
(canopen.profiles.p402.State402), so the master here and canopen's own 402 node agree on every bit.

- `PowerStateMachine` is the drive's side: the transitions of CiA 402's state diagram (numbers as in the standard),
  for the simulated drives, so a master that skips a step or sends the wrong command fails against them as it would
  against a drive.
- `enable_operation` and `safe_stop` are the master's side, over SDO: walk a drive to OPERATION ENABLED (with a fault
  reset when it is in FAULT) or to its safe state, waiting for the statusword after every command, with a timeout
  per transition. A drive whose controlword is mapped into an RxPDO still takes SDO writes to it before the cycle
  starts and after it ends, which is when these run.

It imports only the standard library and canopen.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from canopen.profiles.p402 import State402

__all__ = [
    "CONTROLWORD",
    "STATUSWORD",
    "Cia402Error",
    "PowerStateMachine",
    "enable_operation",
    "safe_stop",
    "state_of",
]

CONTROLWORD, STATUSWORD = 0x6040, 0x6041

NOT_READY = "NOT READY TO SWITCH ON"
SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
READY = "READY TO SWITCH ON"
SWITCHED_ON = "SWITCHED ON"
OPERATION_ENABLED = "OPERATION ENABLED"
QUICK_STOP_ACTIVE = "QUICK STOP ACTIVE"
FAULT_REACTION = "FAULT REACTION ACTIVE"
FAULT = "FAULT"

CW_SHUTDOWN = State402.CW_SHUTDOWN  # 0b0110: transitions 2, 6, 8
CW_SWITCH_ON = State402.CW_SWITCH_ON  # 0b0111: transition 3; "disable operation", transition 5
CW_ENABLE = State402.CW_OPERATION_ENABLED  # 0b1111: transition 4, 16
CW_QUICK_STOP = State402.CW_QUICK_STOP  # 0b0010: transitions 7, 10, 11
CW_DISABLE_VOLTAGE = State402.CW_DISABLE_VOLTAGE  # 0b0000: transitions 7, 9, 10, 12
CW_FAULT_RESET = 0x0080  # bit 7, on its rising edge: transition 15

# statusword bits beside the state pattern: 4 voltage enabled, 5 quick stop (0 = active), 9 remote (CiA 402 6.2)
VOLTAGE_ENABLED, QUICK_STOP_OFF, REMOTE = 0x0010, 0x0020, 0x0200
STATUSWORD_OF = {
    NOT_READY: 0x0000,
    SWITCH_ON_DISABLED: 0x0040,
    READY: 0x0021 | QUICK_STOP_OFF,
    SWITCHED_ON: 0x0023 | QUICK_STOP_OFF | VOLTAGE_ENABLED,
    OPERATION_ENABLED: 0x0027 | QUICK_STOP_OFF | VOLTAGE_ENABLED,
    QUICK_STOP_ACTIVE: 0x0007 | VOLTAGE_ENABLED,
    FAULT_REACTION: 0x000F | VOLTAGE_ENABLED,
    FAULT: 0x0008,
}


def state_of(statusword: int) -> str | None:
    """The state a statusword shows (canopen's State402 masks), None for a pattern CiA 402 does not define."""
    for state, (mask, value) in State402.SW_MASK.items():
        if statusword & mask == value:
            return str(state)
    return None


def _command(controlword: int) -> str | None:
    """The device control command a controlword carries (CiA 402 table 'device control commands', bits 7, 3-0)."""
    if controlword & 0x0082 == 0x0000:
        return "disable voltage"
    if controlword & 0x0086 == 0x0002:
        return "quick stop"
    if controlword & 0x0087 == 0x0006:
        return "shutdown"
    if controlword & 0x008F == 0x0007:
        return "switch on"  # also "disable operation": the same bits, told apart by the state
    if controlword & 0x008F == 0x000F:
        return "enable operation"
    return None


# (state, command) -> (next state, CiA 402 transition number)
_TRANSITIONS: dict[tuple[str, str], tuple[str, int]] = {
    (SWITCH_ON_DISABLED, "shutdown"): (READY, 2),
    (READY, "switch on"): (SWITCHED_ON, 3),
    (SWITCHED_ON, "enable operation"): (OPERATION_ENABLED, 4),
    (OPERATION_ENABLED, "switch on"): (SWITCHED_ON, 5),  # disable operation
    (SWITCHED_ON, "shutdown"): (READY, 6),
    (READY, "quick stop"): (SWITCH_ON_DISABLED, 7),
    (READY, "disable voltage"): (SWITCH_ON_DISABLED, 7),
    (OPERATION_ENABLED, "shutdown"): (READY, 8),
    (OPERATION_ENABLED, "disable voltage"): (SWITCH_ON_DISABLED, 9),
    (SWITCHED_ON, "quick stop"): (SWITCH_ON_DISABLED, 10),
    (SWITCHED_ON, "disable voltage"): (SWITCH_ON_DISABLED, 10),
    (OPERATION_ENABLED, "quick stop"): (QUICK_STOP_ACTIVE, 11),
    (QUICK_STOP_ACTIVE, "disable voltage"): (SWITCH_ON_DISABLED, 12),
}


@dataclass
class PowerStateMachine:
    """A drive's CiA 402 power state machine.

    `controlword(cw)` applies a command; `tick()` runs the drive's own transitions (at each SYNC in the simulated
    drive): 1 (NOT READY -> SWITCH ON DISABLED once initialised), 12 after a quick stop (quick stop option code 2,
    CiA 402's default behaviour of 0x605A: the motor has stopped, then SWITCH ON DISABLED) and 14 (FAULT REACTION
    ACTIVE -> FAULT); `fault()` is transition 13 from any state. Transition 16 (QUICK STOP ACTIVE -> OPERATION
    ENABLED) exists only for option codes 5-8 and is not taken. `history` lists (transition number, new state).
    """

    state: str = NOT_READY
    last_controlword: int = 0
    history: list[tuple[int, str]] = field(default_factory=list)

    @property
    def statusword(self) -> int:
        return STATUSWORD_OF[self.state] | REMOTE

    @property
    def enabled(self) -> bool:
        return self.state == OPERATION_ENABLED

    def _go(self, number: int, state: str) -> None:
        self.state = state
        self.history.append((number, state))

    def controlword(self, cw: int) -> str:
        """Apply a controlword; a command the current state has no transition for leaves it unchanged."""
        rising_reset = cw & CW_FAULT_RESET and not self.last_controlword & CW_FAULT_RESET
        self.last_controlword = cw
        if self.state == FAULT:
            if rising_reset:
                self._go(15, SWITCH_ON_DISABLED)
            return self.state
        command = _command(cw)
        if self.state == READY and command == "enable operation":  # "switch on + enable operation": 3, then 4
            self._go(3, SWITCHED_ON)
        step = _TRANSITIONS.get((self.state, command)) if command else None
        if step is not None:
            self._go(step[1], step[0])
        return self.state

    def tick(self) -> str:
        if self.state == NOT_READY:
            self._go(1, SWITCH_ON_DISABLED)
        elif self.state == QUICK_STOP_ACTIVE:
            self._go(12, SWITCH_ON_DISABLED)
        elif self.state == FAULT_REACTION:
            self._go(14, FAULT)
        return self.state

    def fault(self) -> str:
        if self.state not in (FAULT, FAULT_REACTION):
            self._go(13, FAULT_REACTION)
        return self.state


# --- the master's side ------------------------------------------------------------------------------------------


class Cia402Error(Exception):
    """A drive did not reach the state it was commanded to; the message says which, where it stayed and what to do."""


ReadFn = Callable[[], int]  # reads the statusword
WriteFn = Callable[[int], None]  # writes the controlword

# the command that leads from each state toward OPERATION ENABLED, and the state it must lead to
_TOWARD_ENABLED = {
    SWITCH_ON_DISABLED: (CW_SHUTDOWN, READY),
    READY: (CW_SWITCH_ON, SWITCHED_ON),
    SWITCHED_ON: (CW_ENABLE, OPERATION_ENABLED),
    QUICK_STOP_ACTIVE: (CW_DISABLE_VOLTAGE, SWITCH_ON_DISABLED),
}


def _wait_for(
    name: str, read: ReadFn, want: tuple[str, ...], after: str, timeout_s: float, poll_s: float
) -> tuple[str, int]:
    deadline = time.monotonic() + timeout_s
    while True:
        sw = read()
        state = state_of(sw)
        if state in want:
            return state, sw
        if time.monotonic() >= deadline:
            raise Cia402Error(
                f"{name}: still {state or 'in an undefined state'} (statusword 0x{sw:04X}) {1e3 * timeout_s:.0f} ms "
                f"after {after}, expected {' or '.join(want)}. Check the drive's power stage supply, its enable "
                "input and its error history (0x1003); the drive was left as it is."
            )
        time.sleep(poll_s)


def enable_operation(
    name: str,
    read: ReadFn,
    write: WriteFn,
    *,
    timeout_s: float = 0.5,
    poll_s: float = 0.002,
    fault_reset: bool = True,
) -> list[str]:
    """Walk one drive to OPERATION ENABLED: from FAULT by a fault reset (transition 15), then shutdown (2), switch
    on (3) and enable operation (4), each awaited in the statusword within `timeout_s`. Returns the states passed
    through, the first being where the drive was. Raises Cia402Error naming the drive and the step."""
    state, sw = _wait_for(name, read, tuple(STATUSWORD_OF), "the set-up", timeout_s, poll_s)
    path = [state]
    for _ in range(8):  # the longest path: FAULT REACTION, FAULT, SOD, READY, SWITCHED ON, ENABLED
        if state == OPERATION_ENABLED:
            return path
        if state in (NOT_READY, FAULT_REACTION):  # the drive leaves these on its own (transitions 1, 14)
            nxt = SWITCH_ON_DISABLED if state == NOT_READY else FAULT
            state, sw = _wait_for(name, read, (nxt,), f"reaching {state}", timeout_s, poll_s)
        elif state == FAULT:
            if not fault_reset:
                raise Cia402Error(f"{name}: in FAULT (statusword 0x{sw:04X}); not reset, as asked")
            write(0)  # the reset acts on the rising edge of bit 7
            write(CW_FAULT_RESET)
            state, sw = _wait_for(name, read, (SWITCH_ON_DISABLED,), "a fault reset", timeout_s, poll_s)
        else:
            cw, nxt = _TOWARD_ENABLED[state]
            write(cw)
            state, sw = _wait_for(name, read, (nxt,), f"controlword 0x{cw:04X} in {state}", timeout_s, poll_s)
        path.append(state)
    raise Cia402Error(f"{name}: did not reach OPERATION ENABLED (path {' -> '.join(path)})")


def safe_stop(
    name: str, read: ReadFn, write: WriteFn, how: str, *, timeout_s: float = 0.5, poll_s: float = 0.002
) -> str:
    """Bring one drive to its safe state: `quick_stop` (transition 11, then the drive's own 12 to SWITCH ON
    DISABLED; from READY or SWITCHED ON transition 7 or 10) or `disable_operation` (transition 5: SWITCHED ON, the
    power stage on but no torque). A drive not enabled is left as it is. Returns the state reached."""
    state = state_of(read())
    if state not in (OPERATION_ENABLED, SWITCHED_ON, READY) or (
        how == "disable_operation" and state != OPERATION_ENABLED
    ):
        return state or "undefined"
    if how == "disable_operation":
        write(CW_SWITCH_ON)
        return _wait_for(name, read, (SWITCHED_ON,), "disable operation", timeout_s, poll_s)[0]
    if how != "quick_stop":
        raise ValueError(f"safe stop {how!r}: write quick_stop or disable_operation")
    write(CW_QUICK_STOP)
    return _wait_for(name, read, (QUICK_STOP_ACTIVE, SWITCH_ON_DISABLED), "quick stop", timeout_s, poll_s)[0]


class PdoEnabler:
    """The master's walk to OPERATION ENABLED through PDOs, one step per SYNC cycle: fed the statusword the drive's
    TPDO brought in the last cycle, it gives the controlword the RxPDO carries in this one (fault reset on a rising
    edge of bit 7 over two cycles, then shutdown, switch on, enable operation). A state that does not move on within
    `timeout_cycles` of its command sets `error`; `path` lists the states seen, `state` the latest."""

    def __init__(self, name: str, timeout_cycles: int) -> None:
        self.name, self.timeout_cycles = name, max(1, timeout_cycles)
        self.path: list[str] = []
        self.state: str | None = None
        self.error: str | None = None
        self.controlword = CW_DISABLE_VOLTAGE  # what the RxPDO carries until the drive's state is known
        self._since = 0  # cycles the current state has lasted
        self._reset_armed = False

    @property
    def enabled(self) -> bool:
        return self.state == OPERATION_ENABLED

    def step(self, statusword: int | None) -> int:
        if statusword is None or self.error is not None:
            return self.controlword  # no sample yet (or given up): the last command stays
        state = state_of(statusword)
        if state != self.state:
            self.state, self._since = state, 0
            self.path.append(state or f"undefined 0x{statusword:04X}")
        else:
            self._since += 1
        if state == OPERATION_ENABLED:
            self.controlword = CW_ENABLE
            return self.controlword
        if self._since > self.timeout_cycles:
            self.error = (
                f"{self.name}: still {state or 'in an undefined state'} (statusword 0x{statusword:04X}) "
                f"{self._since} cycles after controlword 0x{self.controlword:04X} over its RxPDO. Check the drive's "
                "power stage supply, its enable input and its error history (0x1003)."
            )
            return self.controlword
        if state == FAULT:
            # bit 7 must rise: one cycle without it, the next with it
            self.controlword = CW_FAULT_RESET if self._reset_armed else CW_DISABLE_VOLTAGE
            self._reset_armed = not self._reset_armed
        elif state in _TOWARD_ENABLED:
            self.controlword = _TOWARD_ENABLED[state][0]
        return self.controlword
